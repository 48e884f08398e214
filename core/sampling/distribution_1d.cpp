// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/sampling/distribution_1d.h"

#include <algorithm>
#include <cmath>

namespace gdmlt {

Distribution1D::Distribution1D(const std::vector<float>& weights)
    : pmf_(weights.size(), 0.f), cdf_(weights.size() + 1, 0.0) {
    for (std::size_t i = 0; i < weights.size(); ++i) {
        const float w = weights[i];
        const double clean = (std::isfinite(w) && w > 0.f) ? static_cast<double>(w) : 0.0;
        cdf_[i + 1] = cdf_[i] + clean;
    }
    total_ = cdf_.back();
    if (total_ <= 0.0) return;
    for (std::size_t i = 0; i < weights.size(); ++i)
        pmf_[i] = static_cast<float>((cdf_[i + 1] - cdf_[i]) / total_);
    for (double& c : cdf_) c /= total_;
    cdf_.back() = 1.0;
    // guide_[j]: the first bin whose upper CDF value exceeds j / n, where search() starts for
    // u in [j / n, (j + 1) / n) (Chen and Asau's guide table, 1974): on average one bin to
    // walk. Small distributions are searched by counting and need none.
    if (weights.size() <= kLinearSearchMax) return;
    const std::size_t n = weights.size();
    guide_.resize(n);
    std::size_t bin = 0;
    for (std::size_t j = 0; j < n; ++j) {
        const double start = static_cast<double>(j) / static_cast<double>(n);
        while (bin + 1 < n && !(start < cdf_[bin + 1])) ++bin;
        guide_[j] = static_cast<std::uint32_t>(bin);
    }
}

std::size_t Distribution1D::search(float u, float* u_remapped) const {
    const double target = static_cast<double>(u);
    // The first bin whose upper CDF value exceeds u (what std::upper_bound over cdf_[1 ..]
    // finds); zero-weight bins are never chosen because their upper bound equals their lower
    // bound. The guide table bounds the answer: for u in [j / n, (j + 1) / n) it lies in
    // [guide_[j], guide_[j + 1]], usually one or two bins, searched by halving with selects.
    // A binary search over all bins, a chain of dependent loads, took 8% of the path tracer's
    // time on an image-lit scene (perf, materials_envmap: two searches per environment sample);
    // the guide with walks in both directions still mispredicted its loop exits (7.5%). A NaN
    // u, which no comparison holds for, lands in the last bin as upper_bound's end does.
    const std::size_t n = pmf_.size();
    const double scaled = target * static_cast<double>(n);
    std::size_t cell = scaled >= 0.0 ? std::min(static_cast<std::size_t>(scaled), n - 1) : 0;
    if (std::isnan(target)) cell = n - 1;
    std::size_t lo = guide_[cell];
    const std::size_t hi = cell + 1 < n ? guide_[cell + 1] : n - 1;
    for (std::size_t length = hi - lo + 1; length > 1;) {
        const std::size_t half = length / 2;
        lo = !(target < cdf_[lo + half]) ? lo + half : lo;
        length -= half;
    }
    // The cell comes from a rounded product, which can disagree with the bounds j / n the guide
    // was built on for u within an ulp of one: then the bin is a neighbour of the range (a
    // branch that is almost never taken, unlike a division to check the cell).
    while (lo > 0 && target < cdf_[lo]) --lo;
    while (lo + 1 < n && !(target < cdf_[lo + 1])) ++lo;
    return finish_search(lo, target, u_remapped);
}

std::size_t Distribution1D::linear_search(float u, float* u_remapped) const {
    const double target = static_cast<double>(u);
    // The bin search() finds: the number of upper bounds cdf_[1 .. n-1] that u is not below,
    // compared as upper_bound compares (!(u < c)), so that even a NaN u lands in the same bin.
    std::size_t index = 0;
    for (std::size_t k = 1; k < pmf_.size(); ++k) index += !(target < cdf_[k]) ? 1 : 0;
    return finish_search(index, target, u_remapped);
}

std::size_t Distribution1D::finish_search(std::size_t index, double target,
                                          float* u_remapped) const {
    // Guard against u rounding onto a gap. The bin's weight is tested first: that branch goes
    // one way unless the distribution has empty bins, while `index > 0` is as random as u
    // (perf: its mispredictions made this function 3.6% of the path tracer's time).
    while (pmf_[index] == 0.f && index > 0) --index;
    if (u_remapped) {
        const double width = cdf_[index + 1] - cdf_[index];
        const double r = width > 0.0 ? (target - cdf_[index]) / width : 0.0;
        *u_remapped = std::clamp(static_cast<float>(r), 0.f, 0x1.fffffep-1f);
    }
    return index;
}

}  // namespace gdmlt
