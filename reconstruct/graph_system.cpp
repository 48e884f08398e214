// SPDX-License-Identifier: GPL-3.0-or-later
#include "reconstruct/graph_system.h"

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace gdmlt::reconstruct::detail {
namespace {

bool finite3(const float* v) {
    return std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]);
}

float sanitize_variance(float v) {
    if (std::isnan(v)) return std::numeric_limits<float>::infinity();  // unknown: no trust
    return std::max(v, 0.f);
}

}  // namespace

CompiledGraph compile_graph(const ReconstructInput& input, ReconstructStats& stats) {
    const PixelGraph& g = input.graph;
    if (g.width <= 0 || g.height <= 0) throw std::invalid_argument("reconstruct: empty graph");
    if (input.primal.width != g.width || input.primal.height != g.height ||
        input.primal.channels != 3)
        throw std::invalid_argument("reconstruct: primal must be RGB and of the graph's size");
    const std::size_t edges = g.edge_count();
    if (g.to.size() != edges || g.difference.size() != 3 * edges)
        throw std::invalid_argument("reconstruct: graph arrays of inconsistent size");
    if (!g.weight.empty() && g.weight.size() != edges)
        throw std::invalid_argument("reconstruct: graph weights of inconsistent size");
    if (!g.variance.empty() && g.variance.size() != edges)
        throw std::invalid_argument("reconstruct: graph variances of inconsistent size");
    const bool has_variance_image = !input.primal_variance.pixels.empty();
    if (has_variance_image &&
        (input.primal_variance.width != g.width || input.primal_variance.height != g.height ||
         input.primal_variance.channels != 1))
        throw std::invalid_argument("reconstruct: primal variance must be 1-channel, same size");

    CompiledGraph c;
    c.width = g.width;
    c.height = g.height;
    c.pixels = g.node_count();
    const std::size_t n = c.pixels;
    const auto w = static_cast<std::int64_t>(g.width);
    const bool with_variance = !g.variance.empty();

    c.right_weight.assign(n, 0.f);
    c.down_weight.assign(n, 0.f);
    c.right_difference.assign(3 * n, 0.f);
    c.down_difference.assign(3 * n, 0.f);
    if (with_variance) {
        c.right_variance.assign(n, 0.f);
        c.down_variance.assign(n, 0.f);
    }

    // Sequential: one pass over the edges, cheap next to any solve, and keeps the placement
    // (which duplicate goes to the lattice slot) independent of threads.
    for (std::size_t e = 0; e < edges; ++e) {
        const std::int64_t a = g.from[e];
        const std::int64_t b = g.to[e];
        if (a < 0 || b < 0 || a >= static_cast<std::int64_t>(n) ||
            b >= static_cast<std::int64_t>(n))
            throw std::invalid_argument("reconstruct: edge " + std::to_string(e) +
                                        " has a pixel index out of range");
        const float weight = g.weight.empty() ? 1.f : g.weight[e];
        const float* d = &g.difference[3 * e];
        if (!std::isfinite(weight) || !finite3(d)) {
            ++stats.dropped_nonfinite_edges;
            continue;
        }
        if (weight < 0.f) {
            ++stats.dropped_negative_weight_edges;
            continue;
        }
        if (weight == 0.f || a == b) {
            ++stats.ignored_edges;
            continue;
        }
        const float var = with_variance ? sanitize_variance(g.variance[e]) : 0.f;
        // Orient lattice edges from the smaller index; flip the difference accordingly.
        const std::int64_t lo = std::min(a, b), hi = std::max(a, b);
        const float sign = (lo == a) ? 1.f : -1.f;
        std::vector<float>* slot_weight = nullptr;
        std::vector<float>* slot_difference = nullptr;
        std::vector<float>* slot_variance = nullptr;
        if (hi == lo + 1 && (lo % w) != w - 1) {
            slot_weight = &c.right_weight;
            slot_difference = &c.right_difference;
            slot_variance = &c.right_variance;
        } else if (hi == lo + w) {
            slot_weight = &c.down_weight;
            slot_difference = &c.down_difference;
            slot_variance = &c.down_variance;
        }
        const auto l = static_cast<std::size_t>(lo);
        if (slot_weight && (*slot_weight)[l] == 0.f) {
            (*slot_weight)[l] = weight;
            for (int k = 0; k < 3; ++k) (*slot_difference)[3 * l + k] = sign * d[k];
            if (with_variance) (*slot_variance)[l] = var;
        } else {
            c.irregular_from.push_back(static_cast<std::int32_t>(a));
            c.irregular_to.push_back(static_cast<std::int32_t>(b));
            c.irregular_difference.insert(c.irregular_difference.end(), d, d + 3);
            c.irregular_weight.push_back(weight);
            if (with_variance) c.irregular_variance.push_back(var);
        }
    }

    if (c.has_irregular()) {
        // CSR incidence: counts, prefix sums, then fill in edge order (deterministic).
        c.csr_offset.assign(n + 1, 0);
        for (std::size_t e = 0; e < c.irregular_from.size(); ++e) {
            ++c.csr_offset[static_cast<std::size_t>(c.irregular_from[e]) + 1];
            ++c.csr_offset[static_cast<std::size_t>(c.irregular_to[e]) + 1];
        }
        for (std::size_t i = 0; i < n; ++i) c.csr_offset[i + 1] += c.csr_offset[i];
        c.csr_edge.resize(static_cast<std::size_t>(c.csr_offset[n]));
        std::vector<std::int32_t> fill(c.csr_offset.begin(), c.csr_offset.end() - 1);
        for (std::size_t e = 0; e < c.irregular_from.size(); ++e) {
            c.csr_edge[static_cast<std::size_t>(
                fill[static_cast<std::size_t>(c.irregular_from[e])]++)] =
                static_cast<std::int32_t>(e);
            c.csr_edge[static_cast<std::size_t>(
                fill[static_cast<std::size_t>(c.irregular_to[e])]++)] =
                static_cast<std::int32_t>(e);
        }
    }

    c.primal.assign(3 * n, 0.0);
    c.has_primal.assign(n, 0);
    std::int64_t missing = 0;
    for (std::size_t i = 0; i < n; ++i) {
        const float* p = &input.primal.pixels[3 * i];
        if (finite3(p)) {
            c.has_primal[i] = 1;
            for (int k = 0; k < 3; ++k) c.primal[3 * i + k] = p[k];
        } else {
            ++missing;
        }
    }
    stats.missing_primal_pixels += missing;

    if (has_variance_image) {
        c.primal_variance.resize(n);
        for (std::size_t i = 0; i < n; ++i)
            c.primal_variance[i] = sanitize_variance(input.primal_variance.pixels[i]);
    }
    return c;
}

SystemWeights l2_weights(const CompiledGraph& graph, double alpha) {
    SystemWeights w;
    w.right = graph.right_weight;
    w.down = graph.down_weight;
    w.irregular = graph.irregular_weight;
    w.screen.resize(graph.pixels);
    const double a2 = alpha * alpha;
    for (std::size_t i = 0; i < graph.pixels; ++i) w.screen[i] = graph.has_primal[i] ? a2 : 0.0;
    return w;
}

std::vector<double> initial_guess(const CompiledGraph& graph, bool warm_start) {
    if (warm_start) return graph.primal;
    return std::vector<double>(3 * graph.pixels, 0.0);
}

Image to_image(const CompiledGraph& graph, const std::vector<double>& x) {
    Image image(graph.width, graph.height, 3);
    for (std::size_t k = 0; k < x.size(); ++k) image.pixels[k] = static_cast<float>(x[k]);
    return image;
}

namespace {

/// out = (A v)_i for pixel i, A = diag(screen) + D^T W D. Lattice weights are 0 at the last
/// column / row, so neighbours across the image border contribute 0 (v is always finite).
inline void apply_row(const CompiledGraph& g, const SystemWeights& w, const double* v,
                      std::size_t i, double out[3]) {
    const std::size_t n = g.pixels;
    const auto width = static_cast<std::size_t>(g.width);
    const double* vi = v + 3 * i;
    const double s = w.screen[i];
    double a0 = s * vi[0], a1 = s * vi[1], a2 = s * vi[2];
    const auto edge = [&](double we, std::size_t j) {
        const double* vj = v + 3 * j;
        a0 += we * (vi[0] - vj[0]);
        a1 += we * (vi[1] - vj[1]);
        a2 += we * (vi[2] - vj[2]);
    };
    if (i + 1 < n) edge(w.right[i], i + 1);
    if (i >= 1) edge(w.right[i - 1], i - 1);
    if (i + width < n) edge(w.down[i], i + width);
    if (i >= width) edge(w.down[i - width], i - width);
    if (!g.csr_offset.empty()) {
        for (auto k = static_cast<std::size_t>(g.csr_offset[i]);
             k < static_cast<std::size_t>(g.csr_offset[i + 1]); ++k) {
            const auto e = static_cast<std::size_t>(g.csr_edge[k]);
            const auto other = static_cast<std::size_t>(
                g.irregular_from[e] == static_cast<std::int32_t>(i) ? g.irregular_to[e]
                                                                    : g.irregular_from[e]);
            edge(w.irregular[e], other);
        }
    }
    out[0] = a0;
    out[1] = a1;
    out[2] = a2;
}

/// Right-hand side alpha^2 M p + D^T W g and the diagonal of A, for pixel i.
inline double rhs_and_diag(const CompiledGraph& g, const SystemWeights& w, std::size_t i,
                           double b[3]) {
    const std::size_t n = g.pixels;
    const auto width = static_cast<std::size_t>(g.width);
    const double s = w.screen[i];
    double diag = s;
    for (int k = 0; k < 3; ++k) b[k] = s * g.primal[3 * i + k];
    // Edge from -> to with difference d: pixel `from` gets -w d, pixel `to` gets +w d.
    const auto add = [&](double we, const float* d, double sign) {
        diag += we;
        for (int k = 0; k < 3; ++k) b[k] += sign * we * static_cast<double>(d[k]);
    };
    if (i + 1 < n) add(w.right[i], &g.right_difference[3 * i], -1.0);
    if (i >= 1) add(w.right[i - 1], &g.right_difference[3 * (i - 1)], +1.0);
    if (i + width < n) add(w.down[i], &g.down_difference[3 * i], -1.0);
    if (i >= width) add(w.down[i - width], &g.down_difference[3 * (i - width)], +1.0);
    if (!g.csr_offset.empty()) {
        for (auto k = static_cast<std::size_t>(g.csr_offset[i]);
             k < static_cast<std::size_t>(g.csr_offset[i + 1]); ++k) {
            const auto e = static_cast<std::size_t>(g.csr_edge[k]);
            const double sign = g.irregular_to[e] == static_cast<std::int32_t>(i) ? 1.0 : -1.0;
            add(w.irregular[e], &g.irregular_difference[3 * e], sign);
        }
    }
    return diag;
}

}  // namespace

CgOutcome solve_pcg(const CompiledGraph& g, const SystemWeights& w, std::vector<double>& x,
                    int max_iterations, double tolerance, std::size_t block, CgWorkspace& work) {
    const std::size_t n = g.pixels;
    work.r.resize(3 * n);
    work.p.resize(3 * n);
    work.q.resize(3 * n);
    work.inv_diag.resize(n);
    double* r = work.r.data();
    double* p = work.p.data();
    double* q = work.q.data();
    double* inv_diag = work.inv_diag.data();
    double* xv = x.data();

    // r = b - A x, z = M^-1 r, p = z; sums of b.b, r.r, r.z per channel.
    const auto init = reduce_blocks<9>(n, block, [&](std::size_t begin, std::size_t end) {
        std::array<double, 9> s{};
        for (std::size_t i = begin; i < end; ++i) {
            double b[3], ax[3];
            const double diag = rhs_and_diag(g, w, i, b);
            // A pixel with no screening and no edge has an empty row: keep its value.
            inv_diag[i] = diag > 0.0 ? 1.0 / diag : 0.0;
            apply_row(g, w, xv, i, ax);
            for (int k = 0; k < 3; ++k) {
                const double rk = b[k] - ax[k];
                r[3 * i + k] = rk;
                p[3 * i + k] = inv_diag[i] * rk;
                s[k] += b[k] * b[k];
                s[3 + k] += rk * rk;
                s[6 + k] += rk * p[3 * i + k];
            }
        }
        return s;
    });

    std::array<double, 3> bb{}, rr{}, rz{};
    std::array<bool, 3> active{};
    for (int k = 0; k < 3; ++k) {
        bb[k] = init[k];
        rr[k] = init[3 + k];
        rz[k] = init[6 + k];
        active[k] = bb[k] > 0.0 && rr[k] > tolerance * tolerance * bb[k];
    }
    // A channel with b = 0 has the solution 0 (A is positive definite on every anchored
    // component; on unanchored ones 0 is the minimum-norm solution).
    for (int k = 0; k < 3; ++k) {
        if (bb[k] == 0.0) {
            for (std::size_t i = 0; i < n; ++i) xv[3 * i + k] = 0.0;
            rr[k] = 0.0;
        }
    }
    const auto relative_residual = [&] {
        double worst = 0.0;
        for (int k = 0; k < 3; ++k)
            if (bb[k] > 0.0) worst = std::max(worst, std::sqrt(rr[k] / bb[k]));
        return worst;
    };

    CgOutcome out;
    while ((active[0] || active[1] || active[2]) && out.iterations < max_iterations) {
        // q = A p, p.q
        const auto pq = reduce_blocks<3>(n, block, [&](std::size_t begin, std::size_t end) {
            std::array<double, 3> s{};
            for (std::size_t i = begin; i < end; ++i) {
                apply_row(g, w, p, i, q + 3 * i);
                for (int k = 0; k < 3; ++k) s[k] += p[3 * i + k] * q[3 * i + k];
            }
            return s;
        });
        std::array<double, 3> step{};
        for (int k = 0; k < 3; ++k) {
            if (!active[k]) continue;
            if (!(pq[k] > 0.0) || !std::isfinite(pq[k])) {
                // Loss of positive curvature: only possible from rounding once converged
                // far below tolerance; stop this channel rather than divide by ~0.
                active[k] = false;
                continue;
            }
            step[k] = rz[k] / pq[k];
        }
        // x += a p, r -= a q, z = M^-1 r; r.z and r.r
        const auto sums = reduce_blocks<6>(n, block, [&](std::size_t begin, std::size_t end) {
            std::array<double, 6> s{};
            for (std::size_t i = begin; i < end; ++i) {
                for (int k = 0; k < 3; ++k) {
                    const std::size_t j = 3 * i + static_cast<std::size_t>(k);
                    xv[j] += step[k] * p[j];
                    r[j] -= step[k] * q[j];
                    s[k] += r[j] * r[j] * inv_diag[i];
                    s[3 + k] += r[j] * r[j];
                }
            }
            return s;
        });
        ++out.iterations;
        std::array<double, 3> beta{};
        for (int k = 0; k < 3; ++k) {
            if (!active[k]) continue;
            rr[k] = sums[3 + k];
            if (rr[k] <= tolerance * tolerance * bb[k]) {
                active[k] = false;
                continue;
            }
            beta[k] = sums[k] / rz[k];
            rz[k] = sums[k];
        }
        if (!(active[0] || active[1] || active[2])) break;
        // p = z + beta p (inactive channels: p = 0 so later passes leave them alone)
        for_blocks(n, block, [&](std::size_t begin, std::size_t end) {
            for (std::size_t i = begin; i < end; ++i)
                for (int k = 0; k < 3; ++k) {
                    const std::size_t j = 3 * i + static_cast<std::size_t>(k);
                    p[j] = active[k] ? inv_diag[i] * r[j] + beta[k] * p[j] : 0.0;
                }
        });
    }
    out.relative_residual = relative_residual();
    out.converged = out.relative_residual <= tolerance;
    return out;
}

}  // namespace gdmlt::reconstruct::detail
