// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Bidirectional path tracing (Veach 1997, ch. 10; core/path/bidirectional.h): per pixel
// sample a camera subpath and a light subpath, all (s, t) strategies combined by MIS. Light
// tracing contributions (t = 1) land on other pixels: they are collected per tile and merged
// in tile order after each pass, so the image is the same at any thread count.
#include <atomic>
#include <functional>

#include "core/path/bidirectional.h"
#include "core/render/render_path.h"

namespace gdmlt {

struct BdptRenderSettings {
    int spp = 16;                // camera samples (and light paths) per pixel
    double time_budget_s = 0.0;  // 0: none
    std::uint64_t seed = 0;
    BdptSettings bdpt;
};

/// Renders with BDPT; stats as the path tracer's (samples = camera samples = light paths).
RenderOutput render_bdpt(const Scene& scene, const BdptRenderSettings& settings,
                         const std::atomic<bool>* cancel = nullptr,
                         const std::function<void(const RenderProgress&)>& progress = {});

}  // namespace gdmlt
