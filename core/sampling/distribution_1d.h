// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Discrete distribution proportional to non-negative weights: sampling by binary search on the
// CDF, with the sample re-used (rescaled) for a continuous choice inside the chosen bin.
#include <cstddef>
#include <cstdint>
#include <vector>

namespace gdmlt {

class Distribution1D {
  public:
    Distribution1D() = default;
    /// Negative or non-finite weights are treated as zero. All-zero weights give an empty
    /// distribution (valid() is false).
    explicit Distribution1D(const std::vector<float>& weights);

    bool valid() const { return total_ > 0.0; }
    std::size_t size() const { return pmf_.size(); }
    double total() const { return total_; }
    float pmf(std::size_t index) const { return pmf_[index]; }

    /// Chooses an index with probability pmf(index) from u in [0,1); `u_remapped` receives a
    /// fresh uniform number in [0,1) for further use.
    std::size_t sample(float u, float* u_remapped = nullptr) const {
        // One entry (a scene with one light, a light of one triangle): no search. Inline, as
        // the path tracer calls this twice per bounce for next-event estimation.
        if (pmf_.size() == 1) {
            if (u_remapped) *u_remapped = u;
            return 0;
        }
        return pmf_.size() <= kLinearSearchMax ? linear_search(u, u_remapped)
                                               : search(u, u_remapped);
    }

  private:
    /// Up to this many bins (a quad light's 2 triangles, a handful of lights) the bin is found
    /// by counting, without branches: the path tracer calls this with random u once or twice
    /// per vertex, and a binary search's branches then mispredict about half the time (perf:
    /// 5% of the path tracer's time went to the comparison of a 2-bin search).
    static constexpr std::size_t kLinearSearchMax = 16;

    std::size_t search(float u, float* u_remapped) const;
    std::size_t linear_search(float u, float* u_remapped) const;
    /// The shared end of both searches: the gap guard and the remapped number.
    std::size_t finish_search(std::size_t index, double target, float* u_remapped) const;

    std::vector<float> pmf_;
    std::vector<double> cdf_;           // size()+1 entries, cdf_[0] = 0, cdf_.back() = 1
    std::vector<std::uint32_t> guide_;  // search()'s starting bins (more than 16 bins only)
    double total_ = 0.0;
};

}  // namespace gdmlt
