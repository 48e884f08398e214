// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Scenes built in code for tests: a Mitsuba XML body wrapped into a <scene>, parsed and built.
#include <tbb/global_control.h>

#include <functional>
#include <string>
#include <utility>

#include "core/image/neighbour_set.h"
#include "core/render/render_path.h"
#include "core/scene/scene.h"

namespace gdmlt::test {

/// Parses `<scene version="3.0.0">` + body + `</scene>` (named "test.xml" in messages).
Scene scene_from_xml(const std::string& body, const BuildOptions& options = {});

/// The repository's scenes/<name>.xml with its defaults (the tests' copy of the source tree).
Scene repository_scene(const std::string& name);

/// A sensor block: perspective camera at `origin` looking at the origin, square film.
std::string sensor_xml(int resolution, float fov_deg, const std::string& origin, int spp = 16);

/// A small Cornell box (diffuse walls, two boxes, an area light under the ceiling, one glass
/// sphere when `glass_sphere`), camera included, at `resolution`^2 pixels.
std::string cornell_box_xml(int resolution, bool glass_sphere = false);

/// A box lit only by a small emitting sphere sealed in a glass ball (caustic_glass_light in
/// miniature): next-event estimation from the walls is always blocked by the glass, so the
/// light arrives through light tracing, connections of light subpaths that crossed the glass,
/// and camera paths that hit the light through it.
std::string sealed_light_box_xml(int resolution);

/// Mean and standard error of the pixel means of a 3-channel image over channel `c`.
struct PixelStatistics {
    double mean = 0.0;
    double standard_error = 0.0;
};
PixelStatistics pixel_statistics(const std::vector<float>& rgb, int channel);

/// The render tests' reference: the path tracer at 4096 spp, seed 1, max_depth 8.
RenderOutput reference_render(const Scene& scene);

/// ADAP's graph for a scene: feature pass (4 spp, seed 5) and the default selection.
NeighbourSet adap_graph(const Scene& scene);

/// Mean luminance of an RGB image.
double mean_luminance(const Image& image);

/// The furnace tests' render: path tracer, unbounded depth, Russian roulette from depth 5.
RenderOutput render_unbounded(const Scene& scene, int spp, std::uint64_t seed);

/// Every channel's image mean equals `expected` within 5 standard errors (from the per-pixel
/// spread) plus `relative_model_error` * expected, and the budget makes the standard error
/// smaller than 2% of the expected value (otherwise the test could not fail).
void expect_image_mean(const Image& image, const Rgb& expected, double relative_model_error);

/// Image mean luminance over independent renders, with its standard error from their spread
/// (integrators that splat light paths across pixels make pixels correlated, so the per-pixel
/// spread of one image says nothing), and their average image.
struct IndependentRenders {
    double mean = 0.0;
    double standard_error = 0.0;
    Image average;
};
/// Calls `render(seed)` for seeds 100 .. 100 + runs - 1; every render must drop no sample.
IndependentRenders independent_renders(const std::function<RenderOutput(std::uint64_t)>& render,
                                       int runs);

/// `render()` run twice, with at most one thread and then at most two: determinism tests
/// compare the two results bit for bit.
template <typename Render>
auto at_one_and_two_threads(Render&& render) {
    using Result = decltype(render());
    std::pair<Result, Result> results;
    {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
        results.first = render();
    }
    {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
        results.second = render();
    }
    return results;
}

/// A smooth image with distinct values in every pixel and channel (exact round-trip tests).
Image ramp_image(int w, int h, int channels, float offset);

}  // namespace gdmlt::test
