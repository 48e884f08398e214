// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/sampling/alias_table.h"

#include <algorithm>
#include <cmath>

namespace gdmlt {

AliasTable::AliasTable(const std::vector<float>& weights)
    : columns_(weights.size()), pmf_(weights.size(), 0.f) {
    std::vector<double> scaled(weights.size(), 0.0);
    for (std::size_t i = 0; i < weights.size(); ++i) {
        const float w = weights[i];
        scaled[i] = (std::isfinite(w) && w > 0.f) ? static_cast<double>(w) : 0.0;
        total_ += scaled[i];
    }
    if (!(total_ > 0.0)) {
        total_ = 0.0;
        return;
    }
    // Vose: each column holds 1 / n of the probability; a bin with less than that (scaled
    // below 1) keeps its share of its own column and lends the rest to a bin with more.
    const auto n = static_cast<double>(weights.size());
    std::vector<std::uint32_t> small, large;
    for (std::size_t i = 0; i < weights.size(); ++i) {
        scaled[i] *= n / total_;
        (scaled[i] < 1.0 ? small : large).push_back(static_cast<std::uint32_t>(i));
    }
    std::vector<double> threshold(weights.size(), 1.0);
    std::vector<std::uint32_t> alias(weights.size());
    for (std::size_t i = 0; i < alias.size(); ++i) alias[i] = static_cast<std::uint32_t>(i);
    while (!small.empty() && !large.empty()) {
        const std::uint32_t s = small.back(), l = large.back();
        small.pop_back();
        threshold[s] = scaled[s];
        alias[s] = l;
        scaled[l] -= 1.0 - scaled[s];
        if (scaled[l] < 1.0) {
            large.pop_back();
            small.push_back(l);
        }
    }
    // What is left holds, up to rounding, exactly one column's worth: its own bin always. A
    // zero-weight bin can be left here only when rounding used up the large bins first; it
    // must never be chosen, so its column goes to the heaviest bin instead.
    for (const std::uint32_t i : small) threshold[i] = 1.0;
    for (const std::uint32_t i : large) threshold[i] = 1.0;
    const auto heaviest = static_cast<std::uint32_t>(
        std::max_element(weights.begin(), weights.end(),
                         [](float a, float b) {
                             const auto clean = [](float w) {
                                 return std::isfinite(w) && w > 0.f ? w : 0.f;
                             };
                             return clean(a) < clean(b);
                         }) -
        weights.begin());
    for (std::size_t i = 0; i < weights.size(); ++i)
        if (!(std::isfinite(weights[i]) && weights[i] > 0.f)) {
            threshold[i] = 0.0;
            if (alias[i] == i) alias[i] = heaviest;
        }

    // The probabilities the table itself gives, and the float columns sample() reads.
    std::vector<double> pmf(weights.size(), 0.0);
    for (std::size_t i = 0; i < weights.size(); ++i) {
        Column& c = columns_[i];
        c.threshold = static_cast<float>(threshold[i]);
        c.alias = alias[i];
        c.own_scale = c.threshold > 0.f ? 1.f / c.threshold : 0.f;
        c.alias_scale = c.threshold < 1.f ? 1.f / (1.f - c.threshold) : 0.f;
        pmf[i] += static_cast<double>(c.threshold) / n;
        pmf[c.alias] += (1.0 - static_cast<double>(c.threshold)) / n;
    }
    for (std::size_t i = 0; i < weights.size(); ++i) pmf_[i] = static_cast<float>(pmf[i]);
}

}  // namespace gdmlt
