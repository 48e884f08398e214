// SPDX-License-Identifier: GPL-3.0-or-later
// What accuracy costs in time: the manifold walk on synthetic chains, against the relative
// tolerance and the iteration cap. Each benchmark iteration is one walk (so the reported time is
// the time per walk); counters give the success rate, the mean number of projections per walk
// and the share of failures by reason.
//
// Workloads (built in code, fixed seeds): 256 (base chain, target) pairs per scene, the target
// being the end of a chain traced from the same start in a direction perturbed by up to
// `kPerturbation` radians, so every target is reachable (the walk's failures are its own):
//   glass_sphere_k2  - through a glass sphere (refract in, refract out), IOR 1.5;
//   mirror_inside_k3 - three reflections inside a spherical mirror;
//   convex_mirror_k1 - one reflection off a convex mirror sphere.
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "core/scene/scene_desc.h"
#include "manifold/manifold_walk.h"
#include "manifold/walk_stats.h"

namespace {

using namespace gdmlt;
using namespace gdmlt::manifold;

constexpr double kPerturbation = 0.05;
constexpr int kPairs = 256;

struct Workload {
    Scene scene;
    std::vector<SpecularChain> bases;
    std::vector<ChainEndpoint> targets;
};

Scene scene_from(const std::string& body) {
    return build_scene(
        parse_scene_string("<scene version=\"3.0.0\">" + body + "</scene>", "bench.xml"));
}

Vec3d random_unit(std::mt19937& rng) {
    std::normal_distribution<double> normal;
    for (;;) {
        const Vec3d v(normal(rng), normal(rng), normal(rng));
        if (v.norm() > 1e-3) return v.normalized();
    }
}

Workload make_workload(int kind) {
    static const char* kGlass =
        R"(<shape type="sphere"><float name="radius" value="1"/><bsdf type="dielectric">
           <float name="int_ior" value="1.5"/><float name="ext_ior" value="1"/></bsdf></shape>)";
    static const char* kInside =
        R"(<shape type="sphere"><float name="radius" value="1"/>
           <boolean name="flip_normals" value="true"/><bsdf type="conductor"/></shape>)";
    static const char* kConvex =
        R"(<shape type="sphere"><float name="radius" value="1"/><bsdf type="conductor"/></shape>)";
    Workload w{scene_from(kind == 0 ? kGlass : kind == 1 ? kInside : kConvex), {}, {}};
    std::mt19937 rng(1234 + static_cast<unsigned>(kind));
    std::uniform_real_distribution<double> uniform;
    while (static_cast<int>(w.bases.size()) < kPairs) {
        ChainEndpoint start;
        Vec3d direction;
        std::vector<Scatter> scatters;
        double end_distance = 0.0;
        if (kind == 0) {
            start = point_endpoint(3.0 * random_unit(rng));
            direction = (0.8 * uniform(rng) * random_unit(rng) - start.p).normalized();
            scatters = {Scatter::Refraction, Scatter::Refraction};
            end_distance = 1.5;
        } else if (kind == 1) {
            start = point_endpoint(0.5 * uniform(rng) * random_unit(rng));
            direction = random_unit(rng);
            scatters.assign(3, Scatter::Reflection);
            end_distance = 0.5;
        } else {
            start = point_endpoint(3.0 * random_unit(rng));
            direction = (0.9 * uniform(rng) * random_unit(rng) - start.p).normalized();
            scatters = {Scatter::Reflection};
            end_distance = 2.0;
        }
        const ChainOutcome base =
            trace_new_chain(w.scene, start, direction, scatters, end_distance);
        const Vec3d perturbed =
            (direction + kPerturbation * uniform(rng) * random_unit(rng)).normalized();
        const ChainOutcome moved =
            trace_new_chain(w.scene, start, perturbed, scatters, end_distance);
        if (!base.ok() || !moved.ok()) continue;
        w.bases.push_back(base.chain);
        w.targets.push_back(moved.chain.end);
    }
    return w;
}

const Workload& workload(int kind) {
    static const Workload workloads[3] = {make_workload(0), make_workload(1), make_workload(2)};
    return workloads[kind];
}

void BM_ManifoldWalk(benchmark::State& state) {
    const Workload& w = workload(static_cast<int>(state.range(0)));
    ManifoldConfig config;
    config.relative_tolerance = std::pow(10.0, -static_cast<double>(state.range(1)));
    config.max_iterations = static_cast<int>(state.range(2));
    WalkStats stats;
    std::size_t i = 0;
    for (auto _ : state) {
        const WalkResult r = walk(w.scene, w.bases[i], w.targets[i], config);
        benchmark::DoNotOptimize(r.relative_distance);
        stats.record(r);
        i = (i + 1) % w.bases.size();
    }
    state.counters["success_rate"] = stats.success_rate();
    state.counters["mean_iterations"] = stats.mean_iterations();
    state.counters["mean_iterations_ok"] = stats.mean_successful_iterations();
    const double walks = static_cast<double>(std::max<std::uint64_t>(stats.walks, 1));
    state.counters["not_converged"] =
        static_cast<double>(stats.failure_count(WalkFailure::NotConverged)) / walks;
    state.counters["left_manifold"] =
        static_cast<double>(stats.failure_count(WalkFailure::LeftManifold)) / walks;
    const std::uint64_t other = stats.walks - stats.successes -
                                stats.failure_count(WalkFailure::NotConverged) -
                                stats.failure_count(WalkFailure::LeftManifold);
    state.counters["other_failures"] = static_cast<double>(other) / walks;
}

void arguments(benchmark::internal::Benchmark* b) {
    b->ArgNames({"scene", "tol_exp", "max_iter"});
    for (int scene = 0; scene < 3; ++scene) {
        for (int tolerance : {4, 6, 9, 12}) b->Args({scene, tolerance, 20});
        for (int cap : {2, 3, 5, 10}) b->Args({scene, 9, cap});
    }
}

BENCHMARK(BM_ManifoldWalk)->Apply(arguments)->MinTime(0.2);

}  // namespace

BENCHMARK_MAIN();
