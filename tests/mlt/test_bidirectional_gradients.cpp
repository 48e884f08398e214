// SPDX-License-Identifier: GPL-3.0-or-later
// The bidirectional gradient sampler at unit size (also under ASan/UBSan): every code path it
// has (camera strategies with their shifts, cut-prefix shifts, light tracing shifted through
// glass by manifold walks, unshifted light tracing) runs and gives finite values. Its
// statistics are checked by the render tests (tests/render/test_gdmlt_bidirectional.cpp).
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "core/image/neighbour_set.h"
#include "mlt/gradient_sample.h"
#include "tests/support/scene_fixtures.h"

namespace gdmlt::mlt {
namespace {

struct Outcome {
    std::uint64_t camera_terms_shifted = 0, light_terms = 0, light_splats = 0;
    manifold::ShiftCounters shifts;
};

Outcome run(const Scene& scene, bool with_neighbours, int samples) {
    const Film& film = scene.camera().film();
    const NeighbourSet neighbours = NeighbourSet::lattice(film.crop_width, film.crop_height);
    PathSamplerSettings path;
    path.max_depth = 8;
    BidirectionalGradientScratch scratch;
    BidirectionalGradientSample g;
    PathCounters counters;
    Outcome o;
    for (int i = 0; i < samples; ++i) {
        IndependentStream stream(derive_stream(21, static_cast<std::uint64_t>(i)));
        const Vec2f u = stream.next_2d();
        const Vec2f film_position(u.x() * static_cast<float>(film.width),
                                  u.y() * static_cast<float>(film.height));
        const std::span<const NeighbourLink> links =
            neighbours.links(crop_pixel_index(film, film_position));
        std::vector<LinkEstimate> estimates(links.size());
        sample_bidirectional_gradients(
            scene, film_position, stream, path, manifold::ShiftKind::Auto, links, estimates,
            with_neighbours ? &neighbours : nullptr, scratch, g, counters, o.shifts);
        EXPECT_EQ(g.nonfinite, 0);
        EXPECT_TRUE(is_finite(g.primal));
        for (const LinkEstimate& e : estimates) {
            EXPECT_TRUE(is_finite(e.base) && is_finite(e.offset));
            if (!is_black(e.offset)) ++o.camera_terms_shifted;
        }
        for (const LinkEstimate& e : g.light_estimates)
            EXPECT_TRUE(is_finite(e.base) && is_finite(e.offset));
        for (const BdptSample::Splat& s : g.light_splats) EXPECT_TRUE(is_finite(s.value));
        o.light_terms += g.light_terms.size();
        o.light_splats += g.light_splats.size();
        // Every shifted light tracing term has one estimate per link of its pixel.
        for (const auto& term : g.light_terms)
            EXPECT_EQ(term.count, neighbours.links(term.pixel).size());
    }
    return o;
}

TEST(BidirectionalGradientSample, EveryPathThroughTheSealedLightIsFinite) {
    // 8x8, 400 samples (seed 21): light tracing shifted with the neighbour set (manifold walks
    // through the glass), unshifted without it.
    const Scene scene = test::scene_from_xml(test::sealed_light_box_xml(8));
    const Outcome shifted = run(scene, true, 400);
    EXPECT_GT(shifted.camera_terms_shifted, 0u);
    EXPECT_GT(shifted.light_terms, 50u);
    EXPECT_EQ(shifted.light_splats, 0u);  // an area light: every light path can be shifted
    EXPECT_GT(shifted.shifts.manifold_shifts, 0u);
    const Outcome unshifted = run(scene, false, 400);
    EXPECT_EQ(unshifted.light_terms, 0u);
    EXPECT_EQ(unshifted.light_splats, shifted.light_terms);  // the same samples, the same terms
}

TEST(BidirectionalGradientSample, LightsThatCannotBeShiftedStayUnshifted) {
    // A point light (a delta position: no point on it for a camera-order path to end at):
    // light tracing is splatted unshifted even with a neighbour set.
    const Scene scene = test::scene_from_xml(test::sensor_xml(8, 40.f, "0, 0, 4") + R"(
        <shape type="rectangle"><transform name="to_world"><scale value="3"/><translate z="-1"/></transform></shape>
        <emitter type="point"><point name="position" x="0" y="0" z="1"/><rgb name="intensity" value="10"/></emitter>)");
    const Outcome o = run(scene, true, 400);
    EXPECT_EQ(o.light_terms, 0u);
    EXPECT_GT(o.light_splats, 50u);
    EXPECT_GT(o.camera_terms_shifted, 0u);
}

}  // namespace
}  // namespace gdmlt::mlt
