// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Counters of manifold walks by outcome; one per thread, summed at the end (like PathCounters).
#include <array>
#include <cstdint>

#include "manifold/manifold_walk.h"

namespace gdmlt::manifold {

struct WalkStats {
    std::uint64_t walks = 0;
    std::uint64_t successes = 0;
    std::uint64_t iterations = 0;             // projections attempted, all walks
    std::uint64_t successful_iterations = 0;  // projections attempted by successful walks
    std::uint64_t accepted_steps = 0;
    /// Final outcome by reason (index 0 = None counts successes again).
    std::array<std::uint64_t, kWalkFailureCount> failures{};
    /// Rejected steps by reason, successful walks included.
    std::array<std::uint64_t, kWalkFailureCount> rejected_steps{};

    void record(const WalkResult& r) {
        ++walks;
        iterations += static_cast<std::uint64_t>(r.iterations);
        accepted_steps += static_cast<std::uint64_t>(r.accepted_steps);
        ++failures[static_cast<std::size_t>(r.failure)];
        if (r.ok()) {
            ++successes;
            successful_iterations += static_cast<std::uint64_t>(r.iterations);
        }
        for (std::size_t i = 0; i < kWalkFailureCount; ++i)
            rejected_steps[i] += r.rejected_steps[i];
    }

    WalkStats& operator+=(const WalkStats& o) {
        walks += o.walks;
        successes += o.successes;
        iterations += o.iterations;
        successful_iterations += o.successful_iterations;
        accepted_steps += o.accepted_steps;
        for (std::size_t i = 0; i < kWalkFailureCount; ++i) {
            failures[i] += o.failures[i];
            rejected_steps[i] += o.rejected_steps[i];
        }
        return *this;
    }

    std::uint64_t failure_count(WalkFailure f) const {
        return failures[static_cast<std::size_t>(f)];
    }
    double success_rate() const {
        return walks ? static_cast<double>(successes) / static_cast<double>(walks) : 0.0;
    }
    double mean_iterations() const {
        return walks ? static_cast<double>(iterations) / static_cast<double>(walks) : 0.0;
    }
    double mean_successful_iterations() const {
        return successes
                   ? static_cast<double>(successful_iterations) / static_cast<double>(successes)
                   : 0.0;
    }
};

}  // namespace gdmlt::manifold
