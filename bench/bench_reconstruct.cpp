// SPDX-License-Identifier: GPL-3.0-or-later
// What accuracy costs in time: L2, L1 and CV reconstruction at 512x512 and 1280x720, against
// iteration count and tolerance. Each benchmark reports the RMSE against the clean image as a
// counter; bench/reconstruct_cost.py runs this binary, tabulates medians and plots.
//
// Input: a clean image (GDMLT_BENCH_IMAGE=path to an EXR/PNG rendered image, resized by
// cropping/tiling; otherwise a procedural stand-in with edges, gradients and highlights), a
// primal = clean + Gaussian noise (sigma 0.1 relative to the mean), lattice differences = exact
// + noise (sigma 0.02), as gradient-domain renders have much less noisy gradients than primals.
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <map>
#include <random>
#include <utility>

#include "core/image/image_io.h"
#include "reconstruct/reconstruct.h"

namespace {

using gdmlt::Image;
using namespace gdmlt::reconstruct;

Image procedural(int w, int h) {
    Image img(w, h, 3);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const double u = static_cast<double>(x) / w, v = static_cast<double>(y) / h;
            const bool wall = u < 0.35 || v < 0.2;
            const double light = std::exp(-30.0 * ((u - 0.6) * (u - 0.6) + (v - 0.3) * (v - 0.3)));
            const double checker = ((x / 32 + y / 32) % 2) ? 0.8 : 0.4;
            const double shade = wall ? 0.3 + 0.2 * v : checker * (0.5 + 0.5 * u);
            img(x, y, 0) = static_cast<float>(shade + 3.0 * light);
            img(x, y, 1) = static_cast<float>(0.8 * shade + 2.5 * light);
            img(x, y, 2) = static_cast<float>((wall ? 0.6 : 0.5) * shade + 2.0 * light);
        }
    return img;
}

Image clean_image(int w, int h) {
    const char* path = std::getenv("GDMLT_BENCH_IMAGE");
    if (!path) return procedural(w, h);
    const Image src = gdmlt::read_image(path);
    Image img(w, h, 3);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            for (int c = 0; c < 3; ++c)
                img(x, y, c) = src(x % src.width, y % src.height, c < src.channels ? c : 0);
    return img;
}

struct Case {
    Image clean;
    ReconstructInput input;
};

const Case& make_case(int w, int h) {
    static std::map<std::pair<int, int>, Case> cache;
    auto it = cache.find({w, h});
    if (it != cache.end()) return it->second;
    Case c;
    c.clean = clean_image(w, h);
    double mean = 0.0;
    for (float v : c.clean.pixels) mean += v;
    mean /= static_cast<double>(c.clean.pixels.size());
    std::mt19937 rng(12345);
    std::normal_distribution<double> noise(0.0, 1.0);
    Image primal = c.clean;
    for (float& v : primal.pixels) v += static_cast<float>(0.1 * mean * noise(rng));
    c.input.primal = primal;
    c.input.graph = make_lattice_graph(w, h);
    set_differences_from_image(c.input.graph, c.clean);
    for (float& d : c.input.graph.difference) d += static_cast<float>(0.02 * mean * noise(rng));
    c.input.primal_variance = Image(w, h, 1, static_cast<float>(0.01 * mean * mean));
    return cache.emplace(std::make_pair(w, h), std::move(c)).first->second;
}

double rmse(const Image& a, const Image& b) {
    double s = 0.0;
    for (std::size_t i = 0; i < a.pixels.size(); ++i) {
        const double d = static_cast<double>(a.pixels[i]) - b.pixels[i];
        s += d * d;
    }
    return std::sqrt(s / static_cast<double>(a.pixels.size()));
}

void report(benchmark::State& state, const Case& c, const ReconstructResult& r) {
    state.counters["rmse"] = rmse(r.image, c.clean);
    state.counters["primal_rmse"] = rmse(c.input.primal, c.clean);
    state.counters["iterations"] = r.stats.iterations;
    state.counters["cg_iterations"] = r.stats.cg_iterations;
    state.counters["residual"] = r.stats.final_relative_residual;
    state.counters["setup_s"] = r.stats.seconds_setup;
}

// Args: width, height, -log10(tolerance), max CG iterations.
void BM_L2(benchmark::State& state) {
    const Case& c = make_case(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
    ReconstructConfig config;
    config.method = Method::l2;
    config.cg_tolerance = std::pow(10.0, -static_cast<double>(state.range(2)));
    config.cg_max_iterations = static_cast<int>(state.range(3));
    ReconstructResult r;
    for (auto _ : state) r = solve_l2(c.input, config);
    report(state, c, r);
}

// Args: width, height, IRLS iterations, CG iterations per IRLS iteration.
void BM_L1(benchmark::State& state) {
    const Case& c = make_case(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
    ReconstructConfig config;
    config.method = Method::l1;
    config.irls_iterations = static_cast<int>(state.range(2));
    config.irls_cg_iterations = static_cast<int>(state.range(3));
    config.irls_cg_tolerance = 1e-4;
    config.l1_objective_tolerance = 0.0;  // fixed iteration count: measure cost per iteration
    ReconstructResult r;
    for (auto _ : state) r = solve_l1(c.input, config);
    report(state, c, r);
}

// Args: width, height, iterations, weighted (0/1).
void BM_CV(benchmark::State& state) {
    const Case& c = make_case(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
    ReconstructConfig config;
    config.method = Method::cv;
    config.cv_iterations = static_cast<int>(state.range(2));
    config.cv_use_variance = state.range(3) != 0;
    ReconstructResult r;
    for (auto _ : state) r = solve_cv(c.input, config);
    report(state, c, r);
}

void sizes_l2(benchmark::internal::Benchmark* b) {
    for (auto [w, h] : {std::pair{512, 512}, std::pair{1280, 720}})
        for (int tol : {2, 3, 4, 6}) b->Args({w, h, tol, 1000});
    b->Args({1280, 720, 12, 50});  // the NVIDIA L2D preset: 50 fixed iterations
}
void sizes_l1(benchmark::internal::Benchmark* b) {
    for (auto [w, h] : {std::pair{512, 512}, std::pair{1280, 720}})
        for (auto [outer, inner] : {std::pair{5, 10}, std::pair{10, 15}, std::pair{20, 15},
                                    std::pair{20, 25}, std::pair{20, 50}})
            b->Args({w, h, outer, inner});
}
void sizes_cv(benchmark::internal::Benchmark* b) {
    for (auto [w, h] : {std::pair{512, 512}, std::pair{1280, 720}})
        for (int its : {10, 25, 50, 100})
            for (int weighted : {0, 1}) b->Args({w, h, its, weighted});
}

BENCHMARK(BM_L2)->Apply(sizes_l2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_L1)->Apply(sizes_l1)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_CV)->Apply(sizes_cv)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
