// SPDX-License-Identifier: GPL-3.0-or-later
// A NaN texel in a real input file reaches every integrator as non-finite radiance: each must
// drop and count those samples (the counter is positive, so the guard really ran) and still
// produce an image that is finite everywhere and lit where the input is sane.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include "core/image/image_io.h"
#include "core/render/render_path.h"
#include "mlt/gdmlt.h"
#include "mlt/gdpt.h"
#include "mlt/pssmlt.h"
#include "reconstruct/reconstruct.h"
#include "tests/support/scene_fixtures.h"

namespace gdmlt {
namespace {

namespace fs = std::filesystem;

/// A 2x2 float EXR of 1.0 with one NaN texel, written to a fresh temporary directory that is
/// removed afterwards. The loader accepts it (a texel is data, not syntax; a texture baked by
/// another tool can hold NaN), and emitter radiance reaches the path's value unfiltered: BSDFs
/// zero a non-finite value themselves (a NaN reflectance never reaches a sample), an
/// environment map zeroes its texels at load.
class NanTexture {
  public:
    NanTexture() {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        dir_ = fs::temp_directory_path() /
               ("gdmlt_nonfinite_" + std::to_string(::getpid()) + "_" + info->name());
        fs::remove_all(dir_);
        fs::create_directories(dir_);
        Image texels(2, 2, 3, 1.f);
        for (int c = 0; c < 3; ++c) texels(1, 0, c) = std::numeric_limits<float>::quiet_NaN();
        path_ = (dir_ / "nan_texel.exr").string();
        write_exr(path_, {ExrLayer{"", {"R", "G", "B"}, texels}});
    }
    ~NanTexture() {
        std::error_code ignored;
        fs::remove_all(dir_, ignored);
    }
    NanTexture(const NanTexture&) = delete;
    NanTexture& operator=(const NanTexture&) = delete;

    const std::string& path() const { return path_; }

  private:
    fs::path dir_;
    std::string path_;
};

/// 8x8 pixels of a diffuse wall lit by a grey sky and by a square light 1 in front of it that
/// faces the wall (the camera sees its black back). A quarter of the light (nearest filtering)
/// has NaN radiance, so paths that reach it from the wall, about 5% of them, are NaN; the
/// light's mean is NaN too, so light sampling never picks it (a non-finite weight counts as
/// zero) and only BSDF-sampled paths find it.
Scene nan_texel_scene(const std::string& texture) {
    return test::scene_from_xml(
        test::sensor_xml(8, 40.f, "0, 0, 4") +
        R"(<emitter type="constant"><rgb name="radiance" value="0.5"/></emitter>
        <shape type="rectangle"><bsdf type="diffuse"/></shape>
        <shape type="rectangle"><transform name="to_world"><scale value="0.5"/><rotate x="1" angle="180"/><translate z="1"/></transform>
            <emitter type="area"><texture type="bitmap" name="radiance">
                <string name="filename" value=")" +
        texture + R"("/><string name="filter_type" value="nearest"/>
            </texture></emitter></shape>)");
}

/// Every value finite, and not all zero (dropping everything would also be "finite").
void expect_finite_and_lit(const std::vector<float>& pixels, const std::string& what) {
    double sum_abs = 0.0;
    std::size_t nonfinite = 0;
    for (float v : pixels) {
        if (!std::isfinite(v))
            ++nonfinite;
        else
            sum_abs += std::abs(v);
    }
    EXPECT_EQ(nonfinite, 0u) << what;
    EXPECT_GT(sum_abs, 0.0) << what;
}

TEST(NonfiniteInjection, ThePathTracerDropsAndCountsNanTexelSamples) {
    const NanTexture texture;
    const Scene scene = nan_texel_scene(texture.path());
    RenderSettings settings;
    settings.spp = 64;
    settings.seed = 3;
    const RenderOutput out = render_path(scene, settings);
    EXPECT_GT(out.stats.nonfinite_samples_dropped, 0u);
    RecordProperty("dropped", std::to_string(out.stats.nonfinite_samples_dropped));
    expect_finite_and_lit(out.image.pixels, "path image");
}

TEST(NonfiniteInjection, PssmltDropsAndCountsNanTexelStates) {
    const NanTexture texture;
    const Scene scene = nan_texel_scene(texture.path());
    mlt::PssmltSettings settings;
    settings.seed = 3;
    settings.mutations_per_pixel = 16;
    settings.bootstrap_samples = 4000;
    const mlt::PssmltOutput out = mlt::render_pssmlt(scene, settings);
    EXPECT_GT(out.stats.mutations, 0u);
    EXPECT_GT(out.stats.nonfinite_dropped, 0u);
    RecordProperty("dropped", std::to_string(out.stats.nonfinite_dropped));
    EXPECT_TRUE(std::isfinite(out.stats.b));
    expect_finite_and_lit(out.image.pixels, "pssmlt image");
}

/// The layers a gradient-domain render writes, and the reconstruction from them.
void expect_gradient_render_finite(const GradientBuffers& buffers) {
    expect_finite_and_lit(buffers.primal.pixels, "primal");
    expect_finite_and_lit(buffers.dx.pixels, "dx");
    expect_finite_and_lit(buffers.dy.pixels, "dy");
    expect_finite_and_lit(buffers.very_direct.pixels, "very_direct");
    const Image final_image =
        reconstruct::reconstruct_buffers(buffers, reconstruct::ReconstructConfig{}).image;
    expect_finite_and_lit(final_image.pixels, "reconstruction");
}

TEST(NonfiniteInjection, GdptDropsAndCountsNanTexelSamples) {
    const NanTexture texture;
    const Scene scene = nan_texel_scene(texture.path());
    mlt::GdptSettings settings;
    settings.spp = 64;
    settings.seed = 3;
    const mlt::GdptOutput out = mlt::render_gdpt(scene, settings);
    EXPECT_GT(out.stats.nonfinite_dropped, 0u);
    RecordProperty("dropped", std::to_string(out.stats.nonfinite_dropped));
    expect_gradient_render_finite(out.buffers);
}

/// A small GDMLT render of `scene` (seed 3, 16 mutations per pixel, 4 very direct spp) that
/// must have run its chains and dropped and counted NaN samples; its layers and their
/// reconstruction must be finite and lit.
void expect_gdmlt_drops_and_counts(const Scene& scene) {
    mlt::GdmltSettings settings;
    settings.seed = 3;
    settings.mutations_per_pixel = 16;
    settings.bootstrap_samples = 4000;
    settings.very_direct_samples = 4;
    const mlt::GdmltOutput out = mlt::render_gdmlt(scene, settings);
    EXPECT_GT(out.stats.mutations, 0u);
    EXPECT_GT(out.stats.nonfinite_dropped, 0u);
    ::testing::Test::RecordProperty("dropped", std::to_string(out.stats.nonfinite_dropped));
    EXPECT_TRUE(std::isfinite(out.stats.b));
    expect_gradient_render_finite(out.buffers);
}

TEST(NonfiniteInjection, GdmltDropsAndCountsNanTexelStates) {
    const NanTexture texture;
    expect_gdmlt_drops_and_counts(nan_texel_scene(texture.path()));
}

TEST(NonfiniteInjection, GdmltCountsTheNanSamplesOfItsVeryDirectPass) {
    // The NaN-textured light now faces the camera and lights nothing the chains can reach (a
    // flat light before a grey sky): its NaN texels are seen only directly, by the very direct
    // pass, whose drops must reach the render's count as the chains' do (they were lost).
    const NanTexture texture;
    expect_gdmlt_drops_and_counts(test::scene_from_xml(
        test::sensor_xml(8, 40.f, "0, 0, 4") +
        R"(<emitter type="constant"><rgb name="radiance" value="0.5"/></emitter>
        <shape type="rectangle"><transform name="to_world"><scale value="0.5"/></transform>
            <emitter type="area"><texture type="bitmap" name="radiance">
                <string name="filename" value=")" +
        texture.path() + R"("/><string name="filter_type" value="nearest"/>
            </texture></emitter></shape>)"));
}

}  // namespace
}  // namespace gdmlt
