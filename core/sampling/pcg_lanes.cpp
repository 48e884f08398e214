// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/sampling/pcg_lanes.h"

namespace gdmlt {
namespace {

// The kernel compiled for each instruction set (see core/math/simd.h and the same pattern in
// core/path/diffuse_lanes.cpp).
#pragma GCC push_options
#pragma GCC target("arch=x86-64-v4")
namespace avx512 {
#define GDMLT_LANES_ISA 512
#include "core/sampling/pcg_lanes_kernel.inc"
#undef GDMLT_LANES_ISA
}  // namespace avx512
#pragma GCC pop_options
#pragma GCC push_options
#pragma GCC target("arch=x86-64-v3")
namespace avx2 {
#define GDMLT_LANES_ISA 256
#include "core/sampling/pcg_lanes_kernel.inc"
#undef GDMLT_LANES_ISA
}  // namespace avx2
#pragma GCC pop_options
namespace baseline {
#define GDMLT_LANES_ISA 128
#include "core/sampling/pcg_lanes_kernel.inc"
#undef GDMLT_LANES_ISA
}  // namespace baseline

}  // namespace

Pcg32 PcgLanes::get(std::size_t i) const {
    return Pcg32::from_state(state_[i], increment_[i]);
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
