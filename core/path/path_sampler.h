// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Unidirectional path sampling with next-event estimation and MIS (power heuristic, Veach 1997
// ch. 9), Russian roulette and delta lobes: the estimator every integrator builds on. It reads
// uniform numbers only from a SampleStream, so PSSMLT drives it unchanged.
#include <cstdint>

#include "core/geometry/ray.h"
#include "core/math/types.h"
#include "core/sampling/sample_stream.h"
#include "core/scene/scene.h"

namespace gdmlt {

struct PathSamplerSettings {
    int max_depth = -1;  // Mitsuba's meaning: longest contributing path in segments; -1 = none
    int rr_depth = 5;    // Russian roulette from this depth on
    bool hide_emitters = false;
    /// Shortest contributing path, in segments: 3 leaves out emitters seen directly and direct
    /// lighting (PSSMLT renders those separately when asked, as Mitsuba's pssmlt does).
    int min_depth = 1;
};

/// Counters a path sampler increments; one per thread, summed at the end.
struct PathCounters {
    std::uint64_t camera_rays = 0;
    std::uint64_t bounce_rays = 0;
    std::uint64_t shadow_rays = 0;
    std::uint64_t paths = 0;

    PathCounters& operator+=(const PathCounters& o) {
        camera_rays += o.camera_rays;
        bounce_rays += o.bounce_rays;
        shadow_rays += o.shadow_rays;
        paths += o.paths;
        return *this;
    }
    std::uint64_t rays() const { return camera_rays + bounce_rays + shadow_rays; }
};

/// Number of stream dimensions each bounce consumes, whether it uses them or not, so that a
/// primary-sample coordinate always drives the same decision (Kelemen et al. 2002, sec. 4).
/// Layout per bounce: emitter choice (1), point on emitter (2), BSDF lobe (1), BSDF direction
/// (2), Russian roulette (1).
inline constexpr int kDimensionsPerBounce = 7;
/// Dimensions the camera uses before the first bounce: position inside the pixel (2).
inline constexpr int kCameraDimensions = 2;

/// Radiance arriving along `camera_ray` (towards the camera), estimated from one path.
/// May return a non-finite value only if the scene data are broken; callers drop and count
/// non-finite samples.
Rgb sample_path_radiance(const Scene& scene, const Ray& camera_ray, SampleStream& stream,
                         const PathSamplerSettings& settings, PathCounters& counters);

/// The same estimator driven by an IndependentStream without virtual calls (the path tracer's
/// inner loop); gives bit-identical results to the overload above for the same stream state.
Rgb sample_path_radiance(const Scene& scene, const Ray& camera_ray, IndependentStream& stream,
                         const PathSamplerSettings& settings, PathCounters& counters);

/// Power heuristic with exponent 2 (Veach 1997, eq. 9.13), safe for zero and infinite pdfs.
inline float power_heuristic(float pdf_a, float pdf_b) {
    const float a2 = pdf_a * pdf_a, b2 = pdf_b * pdf_b;
    if (!(a2 > 0.f)) return 0.f;
    if (std::isinf(a2)) return 1.f;
    return a2 / (a2 + b2);
}

}  // namespace gdmlt
