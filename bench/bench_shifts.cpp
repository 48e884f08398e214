// SPDX-License-Identifier: GPL-3.0-or-later
// The seed shift table: per shift family (auto, reconnect, halfvector, replay), what one shift of
// a camera path to the neighbouring pixel costs on a real scene, how often it succeeds and
// whether it is invertible (shifting back returns the base path), which is what the gradient
// estimator's unbiasedness rests on (Lehtinen et al. 2013, sec. 4). Each benchmark iteration is
// one shift by (+1, 0) pixels of the next workload path (so the reported time is the time per
// shift); the counters come from a separate untimed pass over the whole workload:
//   success_rate             - shifts with status ok / shifts;
//   back_ok_rate             - among successful shifts, those whose shift back by (-1, 0) with
//                              the same kind is ok too;
//   round_trip_rate          - among successful shifts, those whose shift back is ok and returns
//                              the base's vertices (within kRoundTripTolerance of the scene's
//                              bounding-sphere diameter) and its `escaped` flag;
//   fail_<status>            - share of shifts failing with that status (statuses that occur);
//   manifold_walks_per_shift - manifold walks attempted per shift (ShiftCounters, forward only);
//   paths, mean_vertices     - the workload: its size and mean number of base vertices.
//
// Workload (built once per process, seed kSeed): kPaths camera paths with at least one vertex,
// each through a uniformly random film position at least one pixel from the border (so the
// shifted position stays on the film), sampled with sample_camera_path at the scene
// integrator's max_depth (kDefaultMaxDepth when the scene leaves it unbounded).
//
// Environment: GDMLT_BENCH_SCENE, the Mitsuba XML scene (default scenes/cbox_glass_sphere.xml);
// GDMLT_BENCH_DEFINES, comma-separated name=value scene parameters as the CLI's -D (e.g.
// "res=64,max_depth=8").
#include <benchmark/benchmark.h>

#include <cstdint>
#include <exception>
#include <iterator>
#include <memory>
#include <string>
#include <vector>

#include "bench/bench_scene.h"
#include "core/path/path.h"
#include "core/sampling/rng.h"
#include "core/sampling/sample_stream.h"
#include "core/scene/scene.h"
#include "core/scene/scene_desc.h"
#include "manifold/shift.h"
#include "mlt/gdmlt.h"

namespace {

using namespace gdmlt;
using namespace gdmlt::manifold;

constexpr int kPaths = 1024;
constexpr int kMaxAttemptsPerPath = 64;  // gives up on scenes the camera barely sees
constexpr std::uint64_t kSeed = 20240611;
constexpr int kDefaultMaxDepth = 12;
/// Round trip: re-traced float geometry through up to max_depth bounces, relative to the
/// scene's bounding-sphere diameter.
constexpr double kRoundTripTolerance = 1e-3;
constexpr ShiftKind kKinds[] = {ShiftKind::Auto, ShiftKind::Reconnect, ShiftKind::HalfVector,
                                ShiftKind::Replay};

struct Workload {
    std::unique_ptr<Scene> scene;
    std::vector<Path> bases;
    double mean_vertices = 0.0;
    double round_trip_tolerance_m = 0.0;  // absolute, in scene units
    std::string error;                    // non-empty: the workload could not be built
};

Workload make_workload() {
    Workload w;
    try {
        w.scene = std::make_unique<Scene>(bench::load_bench_scene("scenes/cbox_glass_sphere.xml"));
        // The path settings as the CLI's gdmlt derives them from the scene's integrator.
        PathSamplerSettings settings = mlt::gdmlt_settings_from_scene(w.scene->integrator()).path;
        if (settings.max_depth < 0) settings.max_depth = kDefaultMaxDepth;
        w.round_trip_tolerance_m = kRoundTripTolerance * 2.0 * w.scene->bounds_radius();

        const Film& film = w.scene->camera().film();
        if (film.width < 3 || film.height < 3) throw InputError("the film has no interior pixel");
        PathCounters counters;
        std::uint64_t vertices = 0;
        for (std::uint64_t i = 0; static_cast<int>(w.bases.size()) < kPaths; ++i) {
            if (i >= static_cast<std::uint64_t>(kPaths) * kMaxAttemptsPerPath)
                throw InputError("too few camera paths hit the scene");
            IndependentStream stream(derive_stream(kSeed, i));
            const Vec2f u = stream.next_2d();
            const Vec2f film_position(1.f + u.x() * static_cast<float>(film.width - 2),
                                      1.f + u.y() * static_cast<float>(film.height - 2));
            Path base = sample_camera_path(*w.scene, film_position, stream, settings, counters);
            if (base.vertices.empty()) continue;
            vertices += base.vertices.size();
            w.bases.push_back(std::move(base));
        }
        w.mean_vertices = static_cast<double>(vertices) / static_cast<double>(w.bases.size());
    } catch (const std::exception& e) {
        w.error = e.what();
    }
    return w;
}

const Workload& workload() {
    static const Workload w = make_workload();
    return w;
}

bool returns_base(const Path& back, const Path& base, double tolerance_m) {
    if (back.escaped != base.escaped || back.vertices.size() != base.vertices.size()) return false;
    for (std::size_t k = 0; k < base.vertices.size(); ++k) {
        const double distance_m =
            (back.vertices[k].si.p - base.vertices[k].si.p).cast<double>().norm();
        if (!(distance_m <= tolerance_m)) return false;
    }
    return true;
}

struct ShiftTable {
    ShiftCounters forward;  // the shifts by (+1, 0) only
    std::uint64_t ok = 0, back_ok = 0, round_trip_ok = 0;
};

ShiftTable measure(const Workload& w, ShiftKind kind) {
    ShiftTable t;
    ShiftCounters backward;
    const Vec2f there(1.f, 0.f), back(-1.f, 0.f);
    for (const Path& base : w.bases) {
        const ShiftResult r = shift_path(*w.scene, base, there, kind, t.forward);
        if (r.status != ShiftStatus::Ok) continue;
        ++t.ok;
        const ShiftResult b = shift_path(*w.scene, r.offset, back, kind, backward);
        if (b.status != ShiftStatus::Ok) continue;
        ++t.back_ok;
        if (returns_base(b.offset, base, w.round_trip_tolerance_m)) ++t.round_trip_ok;
    }
    return t;
}

const ShiftTable& table(const Workload& w, ShiftKind kind) {
    static std::unique_ptr<ShiftTable> tables[std::size(kKinds)];
    std::unique_ptr<ShiftTable>& t = tables[static_cast<std::size_t>(kind)];
    if (!t) t = std::make_unique<ShiftTable>(measure(w, kind));
    return *t;
}

double ratio(std::uint64_t count, std::uint64_t total) {
    return total > 0 ? static_cast<double>(count) / static_cast<double>(total) : 0.0;
}

void BM_Shift(benchmark::State& state, ShiftKind kind) {
    const Workload& w = workload();
    if (!w.error.empty()) {
        state.SkipWithError(w.error.c_str());
        return;
    }
    const ShiftTable& t = table(w, kind);  // untimed: before the loop

    const Vec2f offset(1.f, 0.f);
    ShiftCounters counters;
    std::size_t i = 0;
    for (auto _ : state) {
        ShiftResult r = shift_path(*w.scene, w.bases[i], offset, kind, counters);
        benchmark::DoNotOptimize(r);
        i = (i + 1) % w.bases.size();
    }

    const std::uint64_t shifts = t.forward.shifts;
    state.counters["paths"] = static_cast<double>(w.bases.size());
    state.counters["mean_vertices"] = w.mean_vertices;
    state.counters["success_rate"] = ratio(t.ok, shifts);
    state.counters["back_ok_rate"] = ratio(t.back_ok, t.ok);
    state.counters["round_trip_rate"] = ratio(t.round_trip_ok, t.ok);
    state.counters["manifold_walks_per_shift"] = ratio(t.forward.manifold_walks, shifts);
    for (std::size_t s = 0; s < t.forward.by_status.size(); ++s) {
        const auto status = static_cast<ShiftStatus>(s);
        if (status == ShiftStatus::Ok || t.forward.by_status[s] == 0) continue;
        state.counters[std::string("fail_") + to_string(status)] =
            ratio(t.forward.by_status[s], shifts);
    }
}

[[maybe_unused]] const bool kRegistered = [] {
    for (const ShiftKind kind : kKinds)
        benchmark::RegisterBenchmark((std::string("BM_Shift/") + to_string(kind)).c_str(), BM_Shift,
                                     kind);
    return true;
}();

}  // namespace

BENCHMARK_MAIN();
