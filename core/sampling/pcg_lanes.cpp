// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/sampling/pcg_lanes.h"

namespace gdmlt {
namespace {

// The kernel, compiled for each instruction set of core/math/simd.h (simd_targets.inc).
#define GDMLT_SIMD_KERNEL "core/sampling/pcg_lanes_kernel.inc"
#include "core/math/simd_targets.inc"
#undef GDMLT_SIMD_KERNEL

}  // namespace

Pcg32 PcgLanes::get(std::size_t i) const {
    return Pcg32::from_state(state_[i], increment_[i]);
}

void PcgLanes::seed_samples(std::size_t count, std::uint64_t seed, const Keys& id_a,
                            const Keys& id_b, SimdIsa isa) {
    // derive_stream's first term depends on the seed alone.
    const std::uint64_t seed_bits = mix_bits(seed ^ kStreamSeedSalt);
    switch (isa) {
        case SimdIsa::Avx512:
            avx512::seed_samples(state_.data(), increment_.data(), count, seed_bits, id_a.data(),
                                 id_b.data());
            break;
        case SimdIsa::Avx2:
            avx2::seed_samples(state_.data(), increment_.data(), count, seed_bits, id_a.data(),
                               id_b.data());
            break;
        case SimdIsa::Baseline:
            baseline::seed_samples(state_.data(), increment_.data(), count, seed_bits, id_a.data(),
                                   id_b.data());
            break;
    }
}

void PcgLanes::next_floats(std::size_t count, std::size_t draws, Draws& out, SimdIsa isa) {
    switch (isa) {
        case SimdIsa::Avx512:
            avx512::next_floats(state_.data(), increment_.data(), count, draws, out);
            break;
        case SimdIsa::Avx2:
            avx2::next_floats(state_.data(), increment_.data(), count, draws, out);
            break;
        case SimdIsa::Baseline:
            baseline::next_floats(state_.data(), increment_.data(), count, draws, out);
            break;
    }
}

}  // namespace gdmlt
