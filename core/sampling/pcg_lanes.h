// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Many PCG32 streams (core/sampling/rng.h) advanced together, in structure-of-arrays form so
// that each step runs in SIMD lanes (8 streams per AVX-512 instruction, 4 with AVX2, 2 with
// SSE2: the state is 64 bits). The path tracer's wavefront draws every path's numbers for a
// vertex at once this way: a draw of one stream at a time is about 20 scalar instructions,
// which at 26 draws per path was as much work as all of the diffuse vertex arithmetic.
// Each stream gives exactly what Pcg32::next_float gives, bit for bit
// (tests/core/test_pcg_lanes.cpp).
#include <array>
#include <cstddef>
#include <cstdint>

#include "core/math/simd.h"
#include "core/sampling/rng.h"

namespace gdmlt {

class PcgLanes {
  public:
    static constexpr std::size_t kCapacity = 256;
    static constexpr std::size_t kMaxDraws = 8;
    /// Padded by a cache line per array, as DiffuseLanes::Arrays::Lane (L1 set conflicts).
    using Draws = std::array<std::array<float, kCapacity + 16>, kMaxDraws>;

    /// Stream `i` continues from `rng`'s state.
    void set(std::size_t i, const Pcg32& rng) {
        state_[i] = rng.state();
        increment_[i] = rng.increment();
    }
    /// Identifiers of `seed_samples`, one per stream.
    using Keys = std::array<std::uint64_t, kCapacity>;
    /// Streams i < count become IndependentStream(derive_stream(seed, id_a[i], id_b[i]))'s
    /// (the stream pixel_sample gives sample id_b[i] of pixel id_a[i]), all at once: the
    /// same hashing and seeding (core/sampling/rng.h, sample_stream.h) in SIMD lanes. As in
    /// next_floats, count is rounded up to the vector width (the extra streams get unused
    /// states from whatever the keys hold past count).
    void seed_samples(std::size_t count, std::uint64_t seed, const Keys& id_a, const Keys& id_b,
                      SimdIsa isa = best_simd_isa());
    /// The state stream `i` has reached (for tests and for handing a stream back).
    Pcg32 get(std::size_t i) const;
    /// Stream `from` becomes stream `to` (compaction: drivers keep live streams first).
    void move(std::size_t from, std::size_t to) {
        state_[to] = state_[from];
        increment_[to] = increment_[from];
    }

    /// Draws `draws` (at most kMaxDraws) numbers from each stream i < `count` (count rounded up
    /// to the vector width; streams past it are advanced too and must be unused or
    /// unimportant): out[d][i] is what the d-th call of Pcg32::next_float on stream i returns.
    /// With the kernel built for `isa` (core/math/simd.h).
    void next_floats(std::size_t count, std::size_t draws, Draws& out,
                     SimdIsa isa = best_simd_isa());

  private:
    alignas(64) std::array<std::uint64_t, kCapacity> state_{};
    alignas(64) std::array<std::uint64_t, kCapacity> increment_{};
};

}  // namespace gdmlt
