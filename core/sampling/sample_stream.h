// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// The stream of uniform numbers a path sampler consumes. Core owns the interface so that MLT's
// PrimarySampleVector can drive the very same path sampler (Kelemen et al. 2002: the path is a
// deterministic function of its primary samples). Path samplers must consume a fixed number of
// dimensions per bounce, so that primary-sample coordinates keep their meaning under mutation.
#include "core/math/types.h"
#include "core/sampling/rng.h"

namespace gdmlt {

class SampleStream {
  public:
    virtual ~SampleStream() = default;
    /// Next uniform number in [0, 1).
    virtual float next_1d() = 0;
    /// Moves past `count` coordinates without reading them, so that what follows keeps a fixed
    /// coordinate whatever was read before (BDPT's light subpath after a camera subpath of any
    /// length). Nothing to do for independent samples; primary sample vectors jump.
    virtual void skip(std::size_t count) { static_cast<void>(count); }
    Vec2f next_2d() {
        const float a = next_1d();
        const float b = next_1d();
        return {a, b};
    }
};

/// Independent uniform samples from a PCG32 stream.
class IndependentStream final : public SampleStream {
  public:
    explicit IndependentStream(std::uint64_t stream_key) : rng_(stream_key, mix_bits(stream_key)) {}
    float next_1d() override { return rng_.next_float(); }
    const Pcg32& rng() const { return rng_; }

  private:
    Pcg32 rng_;
};

}  // namespace gdmlt
