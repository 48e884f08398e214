// SPDX-License-Identifier: GPL-3.0-or-later
// Raw Embree on our scenes: the ray rate the renderer could reach if it did nothing but trace
// (issue "throughput": the path tracer's rays/s is stated as a fraction of it). Two query forms,
// both through Accelerator and both the renderer's own calls:
//   BM_Embree/KIND         - one precomputed ray per iteration (rtcIntersect1 / rtcOccluded1, as
//                            the shifts, PSSMLT and BDPT trace);
//   BM_Embree_packet/KIND  - 16 consecutive precomputed rays per iteration (rtcIntersect16 /
//                            rtcOccluded16, as the path tracer's wavefront traces; the rays of
//                            one packet are as unrelated as a wavefront's, camera_pixel's
//                            excepted);
//   BM_Embree_packet/camera_pixel_coherent - camera_pixel's packets flagged coherent, as the
//                            wavefront traces its camera rays (Accelerator::intersect_packet).
// items_per_second is rays per second either way; run with --benchmark_filter and compare at the
// renderer's thread count (the `/threads:2` rows are two threads querying the same BVH, the rate
// summed over both).
//
// Workload (built once per process, fixed seed, untimed), in the proportions of a path tracer:
//   camera    - camera rays through uniformly random film positions (coherent-ish);
//   camera_pixel - camera rays through uniformly random pixels, 64 jittered rays per pixel in a
//               row, as the wavefront takes a pixel's samples (a packet is one pixel's rays);
//   bounce    - from the hit points of those rays, cosine-distributed directions about the
//               geometric normal on the camera's side (incoherent, like diffuse bounces);
//   shadow    - from the same points to a point chosen by Scene::sample_emitter (occlusion
//               queries stopping short of the light, like next-event estimation);
//   random    - origins uniform in the middle 80% of the scene's bounding box (per axis),
//               directions uniform on the sphere, unbounded: a distribution that needs no
//               renderer, so that another renderer's ray rate on the same scene file can be
//               measured the same way (bench/mitsuba_rays.py does so for Mitsuba 3); as
//               intersections (BM_Embree*/random) and as occlusion tests (random_test).
// Scene: GDMLT_BENCH_SCENE / GDMLT_BENCH_DEFINES (bench/bench_scene.h), default scenes/cbox.xml.
#include <benchmark/benchmark.h>

#include <array>
#include <cmath>
#include <exception>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "bench/bench_scene.h"
#include "core/accel/accelerator.h"
#include "core/math/frame.h"
#include "core/sampling/rng.h"
#include "core/sampling/sample_stream.h"
#include "core/sampling/warp.h"

namespace {

using namespace gdmlt;

constexpr int kRays = 1 << 18;
constexpr std::uint64_t kSeed = 20261202;
/// camera_pixel: samples per pixel, consecutive as the path tracer's wavefront takes them.
constexpr int kPixelSamples = 64;

struct Workload {
    std::unique_ptr<Scene> scene;
    std::unique_ptr<Accelerator> accelerator;  // our own, over the scene's shapes
    std::vector<Ray> camera, bounce, shadow;
    std::vector<Ray> camera_pixel;  // kPixelSamples consecutive rays per pixel
    std::vector<Ray> random;        // see the file comment
    std::string error;
};

Workload make_workload() {
    Workload w;
    try {
        w.scene = std::make_unique<Scene>(bench::load_bench_scene("scenes/cbox.xml"));
        w.accelerator = std::make_unique<Accelerator>(w.scene->shapes());
        const Film& film = w.scene->camera().film();
        for (std::uint64_t i = 0; static_cast<int>(w.camera.size()) < kRays; ++i) {
            if (i > static_cast<std::uint64_t>(kRays) * 64)
                throw InputError("too few camera rays hit the scene");
            IndependentStream stream(derive_stream(kSeed, i));
            const Vec2f u = stream.next_2d();
            const Ray ray = w.scene->camera().generate_ray(Vec2f(
                u.x() * static_cast<float>(film.width), u.y() * static_cast<float>(film.height)));
            const SurfaceInteraction si = w.scene->intersect(ray);
            if (!si.valid()) continue;
            w.camera.push_back(ray);
            // Bounce: cosine about the geometric normal turned towards the camera.
            const Vec3f n =
                si.n_geometric.dot(ray.direction) < 0.f ? si.n_geometric : Vec3f(-si.n_geometric);
            const Vec3f direction =
                Frame::from_normal(n).to_world(warp::square_to_cosine_hemisphere(stream.next_2d()));
            w.bounce.push_back(spawn_ray(si.p, si.n_geometric, direction));
            // Shadow: to a sampled emitter point, stopping short of it.
            const EmitterSample light =
                w.scene->sample_emitter(si.p, stream.next_1d(), stream.next_2d());
            if (light.valid()) {
                Ray r = spawn_ray(si.p, si.n_geometric, light.wi);
                r.t_max = light.distance * (1.f - kShadowRayShorten);
                w.shadow.push_back(r);
            }
        }
        // camera_pixel: uniformly random pixels, kPixelSamples jittered rays through each.
        for (std::uint64_t i = 0; static_cast<int>(w.camera_pixel.size()) < kRays; ++i) {
            IndependentStream stream(derive_stream(kSeed + 1, i));
            const Vec2f u = stream.next_2d();
            const float px = std::floor(u.x() * static_cast<float>(film.width));
            const float py = std::floor(u.y() * static_cast<float>(film.height));
            for (int s = 0; s < kPixelSamples; ++s) {
                const Vec2f j = stream.next_2d();
                w.camera_pixel.push_back(
                    w.scene->camera().generate_ray(Vec2f(px + j.x(), py + j.y())));
            }
        }
        const Eigen::AlignedBox3f box = w.scene->bounds();
        for (std::uint64_t i = 0; static_cast<int>(w.random.size()) < kRays; ++i) {
            IndependentStream stream(derive_stream(kSeed + 2, i));
            const Vec3f u(stream.next_1d(), stream.next_1d(), stream.next_1d());
            const Vec3f origin =
                box.min() + (box.max() - box.min()).cwiseProduct(Vec3f::Constant(0.1f) + 0.8f * u);
            w.random.push_back(Ray{origin, warp::square_to_uniform_sphere(stream.next_2d())});
        }
        if (w.shadow.empty()) throw InputError("the scene has no emitter to cast shadow rays to");
    } catch (const std::exception& e) {
        w.error = e.what();
    }
    return w;
}

const Workload& workload() {
    static const Workload w = make_workload();
    return w;
}

enum class Kind { Camera, CameraPixel, Bounce, Shadow, Random, RandomTest };

/// The workload's rays of `kind`, or nullptr (and the benchmark skipped) if it failed to build.
const std::vector<Ray>* rays_of(benchmark::State& state, Kind kind) {
    const Workload& w = workload();
    if (!w.error.empty()) {
        state.SkipWithError(w.error.c_str());
        return nullptr;
    }
    if (kind == Kind::CameraPixel) return &w.camera_pixel;
    if (kind == Kind::Random || kind == Kind::RandomTest) return &w.random;
    return kind == Kind::Camera ? &w.camera : kind == Kind::Bounce ? &w.bounce : &w.shadow;
}

void BM_Embree(benchmark::State& state, Kind kind) {
    const std::vector<Ray>* kind_rays = rays_of(state, kind);
    if (!kind_rays) return;
    const std::vector<Ray>& rays = *kind_rays;
    const Accelerator& accelerator = *workload().accelerator;
    // Threads start at different places so that they do not trace the same ray at once.
    std::size_t i =
        (rays.size() / 2) * static_cast<std::size_t>(state.thread_index()) % rays.size();
    std::int64_t hits = 0;
    for (auto _ : state) {
        if (kind == Kind::Shadow || kind == Kind::RandomTest) {
            hits += accelerator.occluded(rays[i]) ? 1 : 0;
        } else {
            const RayHit hit = accelerator.intersect(rays[i]);
            hits += hit.valid() ? 1 : 0;
        }
        if (++i == rays.size()) i = 0;
    }
    benchmark::DoNotOptimize(hits);
    state.SetItemsProcessed(state.iterations());
    state.counters["hit_rate"] =
        benchmark::Counter(static_cast<double>(hits) / static_cast<double>(state.iterations()),
                           benchmark::Counter::kAvgThreads);
}

void BM_Embree_packet(benchmark::State& state, Kind kind, bool coherent) {
    const std::vector<Ray>* kind_rays = rays_of(state, kind);
    if (!kind_rays) return;
    const std::vector<Ray>& rays = *kind_rays;
    const Accelerator& accelerator = *workload().accelerator;
    constexpr std::size_t kPacket = Accelerator::kPacketSize;
    const std::size_t packets = rays.size() / kPacket;
    if (packets == 0) {
        state.SkipWithError("fewer rays than one packet");
        return;
    }
    // The packets built beforehand, as the wavefront builds its own (RayPacket::set per ray).
    std::vector<RayPacket> ray_packets(packets);
    for (std::size_t q = 0; q < packets; ++q) {
        ray_packets[q].count = static_cast<int>(kPacket);
        for (std::size_t k = 0; k < kPacket; ++k)
            ray_packets[q].set(static_cast<int>(k), rays[q * kPacket + k]);
    }
    std::size_t p = packets / 2 * static_cast<std::size_t>(state.thread_index()) % packets;
    HitPacket hits;
    std::array<bool, kPacket> blocked;
    std::int64_t hit_count = 0;
    for (auto _ : state) {
        if (kind == Kind::Shadow || kind == Kind::RandomTest) {
            accelerator.occluded_packet(ray_packets[p], blocked);
            for (const bool b : blocked) hit_count += b ? 1 : 0;
        } else {
            accelerator.intersect_packet(ray_packets[p], hits, coherent);
            for (const std::int32_t shape : hits.shape) hit_count += shape >= 0 ? 1 : 0;
        }
        if (++p == packets) p = 0;
    }
    benchmark::DoNotOptimize(hit_count);
    const auto rays_traced = state.iterations() * static_cast<std::int64_t>(kPacket);
    state.SetItemsProcessed(rays_traced);
    state.counters["hit_rate"] =
        benchmark::Counter(static_cast<double>(hit_count) / static_cast<double>(rays_traced),
                           benchmark::Counter::kAvgThreads);
}

[[maybe_unused]] const bool kRegistered = [] {
    const auto register_packet = [](const std::string& name, Kind kind, bool coherent) {
        benchmark::RegisterBenchmark(("BM_Embree_packet/" + name).c_str(), BM_Embree_packet, kind,
                                     coherent)
            ->Threads(1)
            ->Threads(2)
            ->UseRealTime();
    };
    const std::pair<const char*, Kind> kinds[] = {{"camera", Kind::Camera},
                                                  {"bounce", Kind::Bounce},
                                                  {"shadow", Kind::Shadow},
                                                  {"random", Kind::Random},
                                                  {"random_test", Kind::RandomTest}};
    for (const auto& [name, kind] : kinds) {
        benchmark::RegisterBenchmark((std::string("BM_Embree/") + name).c_str(), BM_Embree, kind)
            ->Threads(1)
            ->Threads(2)
            ->UseRealTime();
        register_packet(name, kind, false);
    }
    // The wavefront's own camera packets: one pixel's samples, flagged coherent.
    register_packet("camera_pixel", Kind::CameraPixel, false);
    register_packet("camera_pixel_coherent", Kind::CameraPixel, true);
    return true;
}();

}  // namespace

BENCHMARK_MAIN();
