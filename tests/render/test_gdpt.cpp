// SPDX-License-Identifier: GPL-3.0-or-later
// Gradient-domain path tracing converges to the path tracer's image, primal and reconstructed.
#include <gtest/gtest.h>

#include "core/render/render_path.h"
#include "mlt/gdpt.h"
#include "reconstruct/reconstruct.h"
#include "reconstruct/reconstruct_input.h"
#include "tests/support/chi2.h"
#include "tests/support/scene_fixtures.h"

namespace gdmlt {
namespace {

void check_against_path_tracer(bool glass, double primal_bound, double final_bound) {
    const Scene scene = test::scene_from_xml(test::cornell_box_xml(24, glass));
    const RenderOutput reference = test::reference_render(scene);

    mlt::GdptSettings settings;
    settings.spp = 128;
    settings.seed = 3;
    settings.path.max_depth = 8;
    const mlt::GdptOutput out = mlt::render_gdpt(scene, settings);
    EXPECT_EQ(out.stats.nonfinite_dropped, 0u);
    reconstruct::ReconstructConfig config;  // L1, alpha 0.2
    const reconstruct::ReconstructResult final_image =
        reconstruct::reconstruct_buffers(out.buffers, config);

    // The primal image is the primal layer plus the very direct light (not part of the
    // gradients).
    Image primal = out.buffers.primal;
    for (std::size_t i = 0; i < primal.pixels.size(); ++i)
        primal.pixels[i] += out.buffers.very_direct.pixels[i];
    const double primal_error = test::relative_mse(primal.pixels, reference.image.pixels);
    const double final_error = test::relative_mse(final_image.image.pixels, reference.image.pixels);
    EXPECT_LT(primal_error, primal_bound);
    EXPECT_LT(final_error, final_bound);
    // Reconstruction must help, not hurt, at equal samples.
    EXPECT_LT(final_error, primal_error);
    ::testing::Test::RecordProperty("primal_relMSE", std::to_string(primal_error));
    ::testing::Test::RecordProperty("final_relMSE", std::to_string(final_error));
}

TEST(Gdpt, PrimalAndFinalImageConvergeToThePathTracersOnACornellBox) {
    // Seeds 1 (reference, 4096 spp) and 3 (GDPT, 128 spp). Measured: primal 0.0014, final
    // 0.0011. Bounds about 2x the measurement: a wrong MIS weight or Jacobian shows as a
    // systematic error well above them (see also GradientEstimator in tests/manifold).
    check_against_path_tracer(false, 0.003, 0.0025);
}

TEST(Gdpt, PrimalAndFinalImageConvergeToThePathTracersWithAGlassSphere) {
    // Caustics make both estimates heavy-tailed; measured: primal 0.0081, final 0.0059;
    // bounds 2x.
    check_against_path_tracer(true, 0.016, 0.012);
}

TEST(Gdpt, NoHaloAroundALightSeenDirectly) {
    // Directly seen emitters bypass the gradients (very_direct layer, added after the solve):
    // their sharp edges would otherwise enter dx/dy with huge values, and L2 spreads what it
    // cannot fit into a halo around the light (relMSE 0.0199 against the primal's 0.0105 on
    // cbox at 16 spp before). Here: 32x32 box, GDPT at 64 spp (seed 5), plain L2; in the ring
    // of pixels within 2 of the light's outline, the final image's squared relative error may
    // not exceed the primal's. Checked to fail with the very direct light put back into the
    // primal and the gradients.
    const Scene scene = test::scene_from_xml(test::cornell_box_xml(32));
    const RenderOutput reference = test::reference_render(scene);
    mlt::GdptSettings settings;
    settings.spp = 64;
    settings.seed = 5;
    settings.path.max_depth = 8;
    const mlt::GdptOutput out = mlt::render_gdpt(scene, settings);
    reconstruct::ReconstructConfig l2;
    l2.method = reconstruct::Method::l2;
    const Image final_image = reconstruct::reconstruct_buffers(out.buffers, l2).image;

    // The light's outline from a render of the emitters alone (max_depth 1), independent of
    // how the integrator under test splits its layers.
    RenderSettings emitters_only;
    emitters_only.spp = 16;
    emitters_only.path.max_depth = 1;
    const Image seen = render_path(scene, emitters_only).image;
    const Image& direct = out.buffers.very_direct;
    const int w = seen.width, h = seen.height;
    auto lit = [&](int x, int y) { return seen(x, y, 0) + seen(x, y, 1) + seen(x, y, 2) > 0.f; };
    std::vector<char> ring(static_cast<std::size_t>(w) * h, 0);
    int outline = 0;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const bool edge = (x + 1 < w && lit(x, y) != lit(x + 1, y)) ||
                              (y + 1 < h && lit(x, y) != lit(x, y + 1));
            if (!edge) continue;
            ++outline;
            for (int dy = -2; dy <= 3; ++dy)
                for (int dx = -2; dx <= 3; ++dx) {
                    const int rx = x + dx, ry = y + dy;
                    if (rx >= 0 && ry >= 0 && rx < w && ry < h)
                        ring[static_cast<std::size_t>(ry) * w + rx] = 1;
                }
        }
    ASSERT_GT(outline, 4);  // the light is in view (else the test could not fail)
    double final_error = 0.0, primal_error = 0.0;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            if (!ring[static_cast<std::size_t>(y) * w + x]) continue;
            for (int c = 0; c < 3; ++c) {
                const double ref = reference.image(x, y, c);
                const double primal = out.buffers.primal(x, y, c) + direct(x, y, c);
                final_error += sqr(final_image(x, y, c) - ref) / (ref * ref + 0.01);
                primal_error += sqr(primal - ref) / (ref * ref + 0.01);
            }
        }
    EXPECT_LT(final_error, primal_error);
    RecordProperty("ring_error_ratio", std::to_string(final_error / primal_error));
}

}  // namespace
}  // namespace gdmlt
