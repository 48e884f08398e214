// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Wall-clock timing for time budgets and statistics: the steady clock (never jumps with the
// system time), in seconds.
#include <chrono>

namespace gdmlt {

using Clock = std::chrono::steady_clock;

/// Seconds elapsed since `start`.
inline double seconds_since(Clock::time_point start) {
    return std::chrono::duration<double>(Clock::now() - start).count();
}

}  // namespace gdmlt
