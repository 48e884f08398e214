// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Discrete distribution sampled in constant time by Walker's alias method (Walker 1977; the
// table built by Vose's algorithm, IEEE TSE 1991): one uniform number picks a column, one
// comparison decides between the column's own bin and its alias, and the part of the number
// not used for the choice is handed back, uniform in [0, 1), for a continuous choice inside
// the chosen bin. For emitter selection and for a light's triangles, where the path tracer
// draws once or twice per vertex: no search, no division.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace gdmlt {

class AliasTable {
  public:
    AliasTable() = default;
    /// Negative or non-finite weights are treated as zero. All-zero weights give an empty table
    /// (valid() is false).
    explicit AliasTable(const std::vector<float>& weights);

    bool valid() const { return total_ > 0.0; }
    std::size_t size() const { return pmf_.size(); }
    double total() const { return total_; }
    /// The probability with which sample() returns `index`: the table's own (its columns'
    /// shares summed in double), within float rounding of weight / total.
    float pmf(std::size_t index) const { return pmf_[index]; }

    /// Chooses an index with probability pmf(index) from u in [0, 1); `u_remapped` receives a
    /// fresh uniform number in [0, 1) for further use. Zero-weight bins are never chosen.
    std::size_t sample(float u, float* u_remapped = nullptr) const {
        const std::size_t n = columns_.size();
        if (n == 1) {
            if (u_remapped) *u_remapped = u;
            return 0;
        }
        const float scaled = u * static_cast<float>(n);
        // A NaN u (no comparison holds) takes column 0.
        const std::size_t column =
            scaled > 0.f ? std::min(static_cast<std::size_t>(scaled), n - 1) : 0;
        const float f = std::min(scaled - static_cast<float>(column), kOneMinusUlp);
        const Column& c = columns_[column];
        const bool own = f < c.threshold;
        if (u_remapped) {
            const float r = own ? f * c.own_scale : (f - c.threshold) * c.alias_scale;
            *u_remapped = r < kOneMinusUlp ? (r > 0.f ? r : 0.f) : kOneMinusUlp;
        }
        return own ? column : c.alias;
    }

  private:
    static constexpr float kOneMinusUlp = 0x1.fffffep-1f;
    struct Column {
        float threshold = 1.f;    // f below this keeps the column's own bin
        float own_scale = 1.f;    // 1 / threshold: f -> [0, 1) inside the own bin
        float alias_scale = 0.f;  // 1 / (1 - threshold)
        std::uint32_t alias = 0;
    };
    std::vector<Column> columns_;
    std::vector<float> pmf_;
    double total_ = 0.0;
};

}  // namespace gdmlt
