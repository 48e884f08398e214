// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// The x86-64 instruction sets the SIMD kernels (core/path/diffuse_lanes_kernel.inc,
// core/sampling/pcg_lanes_kernel.inc) are compiled for, each under `#pragma GCC target` in a
// namespace of its own, and the choice among them at run time. Every kernel gives the same
// bits on each (IEEE operations lane by lane, no fused multiply-adds), so the choice changes
// speed only.
#include <vector>

namespace gdmlt {

enum class SimdIsa { Baseline, Avx2, Avx512 };

/// The widest instruction set this processor has: x86-64-v4 (AVX-512 F/BW/CD/DQ/VL), else
/// x86-64-v3 (AVX2, FMA), else the x86-64 baseline (SSE2).
inline SimdIsa best_simd_isa() {
    static const SimdIsa best = [] {
        __builtin_cpu_init();
        if (__builtin_cpu_supports("x86-64-v4")) return SimdIsa::Avx512;
        if (__builtin_cpu_supports("x86-64-v3")) return SimdIsa::Avx2;
        return SimdIsa::Baseline;
    }();
    return best;
}

/// Every instruction set this processor runs, narrowest first (tests compare the kernels
/// built for each against the scalar code).
inline std::vector<SimdIsa> available_simd_isas() {
    std::vector<SimdIsa> isas{SimdIsa::Baseline};
    if (best_simd_isa() != SimdIsa::Baseline) isas.push_back(SimdIsa::Avx2);
    if (best_simd_isa() == SimdIsa::Avx512) isas.push_back(SimdIsa::Avx512);
    return isas;
}

}  // namespace gdmlt
