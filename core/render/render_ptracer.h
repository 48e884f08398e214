// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Light tracing (Mitsuba 3's `ptracer`; Veach 1997, sec. 10.2 "particle tracing"; Arvo & Kirk
// 1990): paths start on the emitters and every vertex is connected to the pinhole, splatting
// its contribution to the pixel it lands in. It is BDPT's t = 1 strategy alone, and the check
// of what BDPT needs from the camera (importance, CameraConnection) and the emitters
// (Scene::sample_emitted_ray) and of the adjoint BSDFs (TransportMode::Importance).
//
// What it cannot see: delta surfaces seen directly by the camera (a mirror's reflection of the
// room) and specular chains ending at the camera, since the connection to a pinhole needs a
// BSDF that can be evaluated. Directly visible environment light is added from one camera ray
// per light path per pixel, as Mitsuba 3's ptracer does.
#include <atomic>
#include <functional>

#include "core/render/render_path.h"

namespace gdmlt {

/// How light tracing weighs its paths.
struct PtracerWeights {
    /// false: unweighted (the `ptracer` integrator). true: each path's BDPT MIS weight of
    /// strategy (s, 1) against every strategy of that path (power heuristic; Veach 1997,
    /// sec. 10.3.4), for a render that adds the other strategies' weighted share from elsewhere
    /// (bidirectional GDMLT's light tracing pass). The weights assume BDPT's subpaths with the
    /// same max_depth and roulette (PathSamplerSettings::rr_depth) as that other estimator.
    bool bdpt_mis = false;
    /// With bdpt_mis: BdptConnectionInput::light_tracing_scale.
    float light_tracing_scale = 1.f;
};

/// Renders with light tracing. `settings.spp` is the number of light paths per crop-window
/// pixel (the whole image receives pixel count x spp of them), also the unit of its passes:
/// results are bit-identical across thread counts and pass splits. Stats count light paths
/// as samples.
RenderOutput render_ptracer(const Scene& scene, const RenderSettings& settings,
                            const std::atomic<bool>* cancel = nullptr,
                            const std::function<void(const RenderProgress&)>& progress = {},
                            const PtracerWeights& weights = {});

}  // namespace gdmlt
