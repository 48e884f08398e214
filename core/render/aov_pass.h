// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// The AOV layers of Mitsuba 3's `aov` integrator (core/scene/aov.h): per pixel, the mean over
// `spp` camera rays (film positions drawn as the path tracer draws them, through the film's
// filter) of what each ray's first hit gives; 0 where a ray escapes. Depth is the ray's
// distance from the near clip plane (Mitsuba 3's si.t), indices are gdmlt's (a shape's index
// in the file's order of shapes).
#include <atomic>
#include <cstdint>
#include <vector>

#include "core/image/image_io.h"
#include "core/scene/aov.h"
#include "core/scene/scene.h"

namespace gdmlt {

/// One layer per request, crop-window sized; `seed` gives the pass its own streams.
std::vector<ExrLayer> render_aovs(const Scene& scene, const std::vector<AovRequest>& requests,
                                  int spp, std::uint64_t seed,
                                  const std::atomic<bool>* cancel = nullptr);

}  // namespace gdmlt
