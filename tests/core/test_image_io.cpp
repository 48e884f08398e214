// SPDX-License-Identifier: GPL-3.0-or-later
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <stdexcept>
#include <string>

#include "core/image/gradient_layers.h"
#include "core/image/image_io.h"
#include "core/scene/scene_desc.h"

namespace gdmlt {
namespace {

namespace fs = std::filesystem;

/// A fresh directory per test under the system temp dir, removed afterwards.
class ImageIoTest : public ::testing::Test {
  protected:
    void SetUp() override {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        dir_ =
            fs::temp_directory_path() /
            ("gdmlt_image_io_" + std::string(info->name()) + "_" +
             std::to_string(static_cast<long>(::testing::UnitTest::GetInstance()->random_seed())));
        fs::remove_all(dir_);
    }
    void TearDown() override { fs::remove_all(dir_); }
    fs::path dir_;
};

Image ramp(int w, int h, int channels, float offset) {
    Image img(w, h, channels);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            for (int c = 0; c < channels; ++c)
                img(x, y, c) = offset + 0.37f * static_cast<float>(x) -
                               1.3e-3f * static_cast<float>(y * y) + 17.25f * static_cast<float>(c);
    return img;
}

TEST_F(ImageIoTest, ExrRoundTripOfTwoLayersWithAttributesIsExact) {
    Image main_img = ramp(13, 7, 3, 0.5f);
    Image primal = ramp(13, 7, 3, -2.f);
    // Values that lossy or half-float storage would not keep exactly.
    main_img(0, 0, 0) = 1e30f;
    main_img(1, 0, 1) = std::numeric_limits<float>::denorm_min();
    primal(2, 3, 2) = -0.1f;
    const std::vector<ExrLayer> layers = {{"", {"R", "G", "B"}, main_img},
                                          {"primal", {"R", "G", "B"}, primal}};
    const ExrAttributes attrs = {{"gdmlt.seed", "42"}, {"gdmlt.config", "{\"alpha\": 0.2}"}};
    // The nested directory does not exist yet: the writer must create it.
    const std::string path = (dir_ / "nested" / "out.exr").string();
    write_exr(path, layers, attrs);

    ExrAttributes read_attrs;
    const std::vector<ExrLayer> read = read_exr(path, &read_attrs);
    ASSERT_EQ(read.size(), 2u);
    // Layers come back sorted by name: "" before "primal".
    EXPECT_EQ(read[0].name, "");
    EXPECT_EQ(read[1].name, "primal");
    for (std::size_t i = 0; i < 2; ++i) {
        EXPECT_EQ(read[i].channel_names, (std::vector<std::string>{"R", "G", "B"}));
        EXPECT_EQ(read[i].image, layers[i].image) << "layer " << i << " is not bit-exact";
    }
    EXPECT_EQ(read_attrs.at("gdmlt.seed"), "42");
    EXPECT_EQ(read_attrs.at("gdmlt.config"), "{\"alpha\": 0.2}");
    // No temporary file is left beside the output.
    int files = 0;
    for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir_ / "nested")) ++files;
    EXPECT_EQ(files, 1);
}

TEST_F(ImageIoTest, PngIsWrittenAndReadableWithTheRightSize) {
    Image img(21, 9, 3, 0.f);
    img(20, 8, 0) = 1.f;  // saturated red in the last pixel
    img(0, 0, 1) = std::numeric_limits<float>::quiet_NaN();
    const std::string path = (dir_ / "preview.png").string();
    write_png_srgb(path, img, 0.f);
    const Image read = read_image(path);
    EXPECT_EQ(read.width, 21);
    EXPECT_EQ(read.height, 9);
    EXPECT_EQ(read.channels, 3);
    EXPECT_FLOAT_EQ(read(20, 8, 0), 1.f);
    EXPECT_FLOAT_EQ(read(0, 0, 1), 0.f);  // NaN shown as black
}

TEST_F(ImageIoTest, MissingFileIsAnInputErrorNamingTheFile) {
    const std::string path = (dir_ / "does_not_exist.exr").string();
    try {
        read_exr(path);
        FAIL() << "no exception";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("does_not_exist.exr"), std::string::npos);
    }
    EXPECT_THROW(read_image(path), InputError);
}

TEST_F(ImageIoTest, GradientBuffersRoundTripThroughTheirExrLayersExactly) {
    // Every layer `gdmlt reconstruct` needs to reproduce a render's solve comes back bit for
    // bit, including infinite variances (pixels with fewer than 2 samples); dropping any of
    // them from gradient_layers or gradient_buffers_from_layers fails here.
    const int w = 9, h = 6;
    GradientBuffers b;
    b.primal = ramp(w, h, 3, 0.25f);
    b.dx = ramp(w, h, 3, -1.f);
    b.dy = ramp(w, h, 3, 2.f);
    b.very_direct = ramp(w, h, 3, 5.f);
    b.sample_count = ramp(w, h, 1, 16.f);
    b.primal_variance = ramp(w, h, 1, 1e-3f);
    b.primal_variance(4, 2) = std::numeric_limits<float>::infinity();
    b.dx_variance = ramp(w, h, 1, 3e-3f);
    b.dy_variance = ramp(w, h, 3, 7e-3f);  // the per-channel form comes back as R, G, B
    const std::string path = (dir_ / "raw.exr").string();
    write_exr(path, gradient_layers(b));
    const GradientBuffers r = gradient_buffers_from_layers(read_exr(path), path);
    EXPECT_EQ(r.primal, b.primal);
    EXPECT_EQ(r.dx, b.dx);
    EXPECT_EQ(r.dy, b.dy);
    EXPECT_EQ(r.very_direct, b.very_direct);
    EXPECT_EQ(r.sample_count, b.sample_count);
    EXPECT_EQ(r.primal_variance, b.primal_variance);
    EXPECT_EQ(r.dx_variance, b.dx_variance);
    EXPECT_EQ(r.dy_variance, b.dy_variance);

    // Absent layers stay absent (GDMLT: no sample counts, no variances).
    GradientBuffers chain;
    chain.primal = b.primal;
    chain.dx = b.dx;
    const std::string chain_path = (dir_ / "chain.exr").string();
    write_exr(chain_path, gradient_layers(chain));
    const GradientBuffers c = gradient_buffers_from_layers(read_exr(chain_path), chain_path);
    EXPECT_EQ(c.dx, chain.dx);
    EXPECT_TRUE(c.dy.pixels.empty());
    EXPECT_TRUE(c.sample_count.pixels.empty());
    EXPECT_TRUE(c.primal_variance.pixels.empty());
    EXPECT_TRUE(c.dx_variance.pixels.empty());

    // (Graphs with extra edges: tests/core/test_gradient_layers.cpp.)
    // A file without a primal is not a gradient-domain render.
    EXPECT_THROW(gradient_buffers_from_layers({{"dx", {"R", "G", "B"}, b.dx}}, "x.exr"),
                 InputError);
}

TEST(Srgb, TransferFunctionsAreInversesOfEachOther) {
    // 1e-6 relative: float pow round trips lose a few ulps, nothing more.
    for (int i = 0; i <= 1000; ++i) {
        const float v = static_cast<float>(i) / 1000.f;
        EXPECT_NEAR(srgb_to_linear(linear_to_srgb(v)), v, 1e-6f + 1e-6f * v) << v;
        EXPECT_NEAR(linear_to_srgb(srgb_to_linear(v)), v, 1e-6f + 1e-6f * v) << v;
    }
    EXPECT_NEAR(linear_to_srgb(0.18f), 0.4613561f, 1e-5f);  // the mid-grey anchor
}

}  // namespace
}  // namespace gdmlt
