// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Branch-free float trigonometry for the per-sample direction <-> (u, v) maps of the
// environment map (core/emitter), where libm's atan2f, acosf and sincosf took 14% of a path
// tracer's time on an image-lit scene (perf, materials_envmap): every escaping ray and every
// environment sample made one or two round trips through them. These are accurate to a few
// float ulps of the result, far below a texel of any environment map, and have no
// data-dependent branches for a random direction to mispredict.
#include <cmath>

#include "core/math/types.h"

namespace gdmlt {

/// sin(x) and cos(x) for |x| <= pi/4, from minimax polynomials of degree 7 and 8 (the
/// coefficients of S. Moshier's Cephes sinf/cosf for this interval), within about an ulp of
/// std::sin and std::cos. The path tracer's vectorised vertex (core/path/diffuse_lanes_kernel.inc)
/// evaluates the same expression in SIMD lanes, where libm would be a scalar call per lane;
/// sharing it keeps the two bit for bit equal.
inline void sincos_quarter_pi(float x, float& sin_x, float& cos_x) {
    const float x2 = x * x;
    sin_x = x + x * x2 * (-1.6666654611e-1f + x2 * (8.3321608736e-3f + x2 * -1.9515295891e-4f));
    cos_x =
        1.f - 0.5f * x2 +
        x2 * x2 *
            (4.166664568298827e-2f + x2 * (-1.388731625493765e-3f + x2 * 2.443315711809948e-5f));
}

/// atan(t) for t in [0, 1]: t * P(t^2), P of degree 7 in t^2. The coefficients are our own
/// least-squares fit with Lawson's reweighting towards the minimax error (numpy, 3001
/// Chebyshev nodes on [0, 1]): 3.7e-8 rad in exact arithmetic, 1.5e-7 rad evaluated in float
/// (Horner's rounding), which is about two ulps of pi/4.
inline float atan_unit(float t) {
    const float z = t * t;
    float p = -0.004054559860378504f;
    p = p * z + 0.021862933412194252f;
    p = p * z - 0.05591229349374771f;
    p = p * z + 0.09642194956541061f;
    p = p * z - 0.1390862911939621f;
    p = p * z + 0.19946566224098206f;
    p = p * z - 0.33329859375953674f;
    p = p * z + 0.9999993443489075f;
    return p * t;
}

/// std::atan2(y, x) within 2e-7 rad, without branches: the ratio of the smaller to the larger
/// magnitude lies in [0, 1], and the octant is put back by selects. Signed zeros follow
/// std::atan2 (atan2(+0, -0) = pi, atan2(-0, x) = -0 for x > 0); atan2(0, 0) is 0.
inline float atan2_approx(float y, float x) {
    const float ax = std::abs(x), ay = std::abs(y);
    const float larger = std::max(ax, ay), smaller = std::min(ax, ay);
    const float t = larger > 0.f ? smaller / larger : 0.f;
    float r = atan_unit(t);
    r = ay > ax ? 0.5f * kPi - r : r;
    r = std::signbit(x) ? kPi - r : r;
    return std::copysign(r, y);
}

/// sin(2 pi turns) and cos(2 pi turns). The quadrant comes from 4 * turns rounded (exact in
/// float for |turns| < 2^21; NaN or larger turns are not for this function), and the remainder, at
/// most an eighth of a turn, goes through the
/// [-pi/4, pi/4] polynomial the concentric map shares with the path tracer's lanes
/// (sincos_quarter_pi above): within 2 ulps there, so within a few ulps of the rounded
/// angle here. Exact multiples of a quarter turn give exact 0 and +-1.
inline void sincos_turns(float turns, float& sin_x, float& cos_x) {
    const float quarters = 4.f * turns;
    // Rounded by conversion (one instruction; std::nearbyint is a libm call without SSE4.1).
    const int q = static_cast<int>(quarters + (quarters >= 0.f ? 0.5f : -0.5f));
    float s, c;
    sincos_quarter_pi((quarters - static_cast<float>(q)) * (0.5f * kPi), s, c);
    // Rotate by q quarter turns: (s, c) -> (c, -s) -> (-s, -c) -> (-c, s).
    const int quadrant = q & 3;
    const bool swap = (quadrant & 1) != 0;
    const float s_out = swap ? c : s, c_out = swap ? s : c;
    sin_x = (quadrant == 2 || quadrant == 3) ? -s_out : s_out;
    cos_x = (quadrant == 1 || quadrant == 2) ? -c_out : c_out;
}

}  // namespace gdmlt
