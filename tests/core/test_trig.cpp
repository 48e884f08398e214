// SPDX-License-Identifier: GPL-3.0-or-later
// The branch-free trigonometry of core/math/trig.h against double-precision libm, over fine
// grids and the special values (axes, signed zeros) where an octant or quadrant could flip.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "core/math/trig.h"

namespace gdmlt {
namespace {

TEST(Trig, Atan2ApproxIsWithinTheFitsErrorAndOneRounding) {
    // 400,000 directions around the circle, at three radii (the ratio is scale-free; tiny and
    // huge magnitudes check that nothing over- or underflows). The fit's error evaluated in
    // float is 1.5e-7 rad; the octant's pi/2 - r and pi - r then round to the result's ulp
    // (2.4e-7 near pi) and kPi itself is pi rounded. Bound: 1.6e-7 plus one ulp of the true
    // angle. Seen failing with the x^15 coefficient dropped (18,000 times the bound) and with
    // pi - r taken for y > 0 only (an error of 2 pi in the lower half).
    double worst = 0.0;
    const int steps = 400000;
    for (const float radius : {1.f, 1e-30f, 1e30f})
        for (int k = 0; k < steps; ++k) {
            const double angle = -std::numbers::pi + 2.0 * std::numbers::pi * k / steps;
            const float y = radius * static_cast<float>(std::sin(angle));
            const float x = radius * static_cast<float>(std::cos(angle));
            const double truth = std::atan2(static_cast<double>(y), static_cast<double>(x));
            const auto magnitude = static_cast<float>(std::abs(truth));
            const double ulp = std::nextafter(magnitude, INFINITY) - magnitude;
            worst = std::max(worst, std::abs(atan2_approx(y, x) - truth) / (1.6e-7 + ulp));
        }
    EXPECT_LE(worst, 1.0);
}

TEST(Trig, Atan2ApproxKeepsStdAtan2sAxesAndSignedZeros) {
    // Where std::atan2 is exact (the axes), so is the approximation: the environment map's
    // seam and poles sit there.
    const float values[] = {0.f, -0.f, 1.f, -1.f, 3.5f, -3.5f};
    for (const float y : values)
        for (const float x : values) {
            if ((y != 0.f) && (x != 0.f)) continue;
            if (y == 0.f && x == 0.f && !std::signbit(x)) {
                EXPECT_EQ(std::signbit(atan2_approx(y, x)), std::signbit(y)) << y << " " << x;
                EXPECT_EQ(atan2_approx(y, x), 0.f);
                continue;
            }
            EXPECT_EQ(atan2_approx(y, x), std::atan2(y, x)) << "y " << y << ", x " << x;
        }
}

TEST(Trig, SincosTurnsIsWithinAFewUlpsOfTheTruth) {
    // Every 2^-17 of a turn over [-1, 2] turns against double sine and cosine of 2 pi t: the
    // quarter-turn polynomial is within 2 ulps (Warp.QuarterPi...), and the reduction adds
    // one rounding of the remainder times pi/2; 1.2e-7 is two ulps of values just below 1.
    // Seen failing with the quadrants' signs swapped (error 2) and with the remainder
    // multiplied by pi instead of pi/2.
    double worst = 0.0;
    for (int k = -(1 << 17); k <= 2 * (1 << 17); ++k) {
        const float t = static_cast<float>(k) / static_cast<float>(1 << 17) + 0x1p-21f;
        float s = 0.f, c = 0.f;
        sincos_turns(t, s, c);
        const double angle = 2.0 * std::numbers::pi * static_cast<double>(t);
        worst = std::max({worst, std::abs(s - std::sin(angle)), std::abs(c - std::cos(angle))});
    }
    EXPECT_LT(worst, 1.2e-7);
    // Quarter turns are exact.
    for (int q = -4; q <= 8; ++q) {
        float s = 0.5f, c = 0.5f;
        sincos_turns(0.25f * static_cast<float>(q), s, c);
        const int quadrant = ((q % 4) + 4) % 4;
        EXPECT_EQ(s, quadrant == 1 ? 1.f : quadrant == 3 ? -1.f : 0.f) << q;
        EXPECT_EQ(c, quadrant == 0 ? 1.f : quadrant == 2 ? -1.f : 0.f) << q;
    }
}

}  // namespace
}  // namespace gdmlt
