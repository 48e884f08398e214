// SPDX-License-Identifier: GPL-3.0-or-later
#include <gtest/gtest.h>
#include <link.h>
#include <sys/stat.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <stdexcept>
#include <string>

#include "core/image/image_io.h"
#include "core/scene/scene_desc.h"
#include "tests/support/scene_fixtures.h"

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

TEST_F(ImageIoTest, ExrRoundTripOfTwoLayersWithAttributesIsExact) {
    Image main_img = test::ramp_image(13, 7, 3, 0.5f);
    Image primal = test::ramp_image(13, 7, 3, -2.f);
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

/// Whether a shared library whose file name contains `name` is loaded in this process.
bool library_loaded(const std::string& name) {
    struct Search {
        std::string name;
        bool found = false;
    } search{name};
    ::dl_iterate_phdr(
        [](dl_phdr_info* info, std::size_t, void* data) {
            auto* s = static_cast<Search*>(data);
            if (info->dlpi_name && std::string(info->dlpi_name).find(s->name) != std::string::npos)
                s->found = true;
            return 0;
        },
        &search);
    return search.found;
}

TEST_F(ImageIoTest, OpenImageIoIsLoadedOnlyToReadAFormatOtherThanExr) {
    // Linked in, OpenImageIO's 250 libraries took 0.33 s of every start-up
    // (core/image/oiio_codec.h). Writing EXR and PNG and reading EXR must not load it; reading
    // a PNG must, and give the pixels back. Each test is a process of its own under ctest;
    // run with the others in one process, a test before this one may have read a PNG.
    if (library_loaded("libgdmlt_oiio_codec")) GTEST_SKIP() << "the codec was loaded already";
    ASSERT_FALSE(library_loaded("libOpenImageIO")) << "linked into the test executable";
    Image img(5, 4, 3, 0.25f);
    img(4, 3, 2) = 3.5f;
    img(1, 2, 0) = -1.f;
    const std::string exr = (dir_ / "rgb.exr").string(), png = (dir_ / "rgb.png").string();
    write_exr(exr, {{"", {"R", "G", "B"}, img}});
    write_png_srgb(png, img);
    ImageFileInfo info;
    info.integer_format = true;
    const Image from_exr = read_image(exr, &info);
    EXPECT_EQ(from_exr, img);
    EXPECT_FALSE(info.integer_format);
    EXPECT_FALSE(library_loaded("libOpenImageIO"));
    const Image from_png = read_image(png, &info);
    EXPECT_TRUE(library_loaded("libOpenImageIO"));
    EXPECT_TRUE(info.integer_format);
    EXPECT_EQ(from_png.width, 5);
    EXPECT_FLOAT_EQ(from_png(4, 3, 2), 1.f);  // clamped to white
    EXPECT_FLOAT_EQ(from_png(0, 0, 0), std::round(255.f * linear_to_srgb(0.25f)) / 255.f);
}

TEST_F(ImageIoTest, ExrOfAnyLayoutReadsAsOpenImageIoReadsIt) {
    // read_image reads EXRs of R, G, B (A) or Y (A) itself, and gives every other EXR to
    // OpenImageIO: both ways give the channels OpenImageIO's order and values. Checked against
    // OpenImageIO directly through the codec by a file it must take (a named layer).
    const Image rgba = test::ramp_image(6, 3, 4, 0.5f), y = test::ramp_image(6, 3, 1, 2.f);
    const std::string a = (dir_ / "rgba.exr").string(), b = (dir_ / "y.exr").string(),
                      c = (dir_ / "layer.exr").string();
    write_exr(a, {{"", {"R", "G", "B", "A"}, rgba}});
    write_exr(b, {{"", {"Y"}, y}});
    write_exr(c, {{"diffuse", {"R", "G", "B"}, test::ramp_image(6, 3, 3, 1.f)}});
    EXPECT_EQ(read_image(a), rgba);
    EXPECT_EQ(read_image(b), y);
    const Image layer = read_image(c);  // OpenImageIO's reading
    EXPECT_EQ(layer, test::ramp_image(6, 3, 3, 1.f));
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

TEST_F(ImageIoTest, AFifoOrADeviceIsAnInputErrorNotAHang) {
    // A texture or an EXR to reconstruct named /dev/zero or a FIFO hung the reader.
    fs::create_directories(dir_);
    const fs::path fifo = dir_ / "texture.exr";
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    for (const std::string& path : {fifo.string(), std::string("/dev/zero")}) {
        for (const bool exr : {true, false}) {
            try {
                if (exr)
                    read_exr(path);
                else
                    read_image(path);
                FAIL() << path << " was read";
            } catch (const InputError& e) {
                EXPECT_NE(std::string(e.what()).find("not a regular file"), std::string::npos)
                    << e.what();
            }
        }
    }
}

TEST_F(ImageIoTest, SameFileSeesThroughSpellingsAndLinks) {
    // Outputs must not replace the scene, the input or each other however they are spelled:
    // the render's and reconstruct's checks both ask same_file.
    fs::create_directories(dir_ / "sub");
    { std::ofstream(dir_ / "a.exr") << "a"; }
    { std::ofstream(dir_ / "b.exr") << "b"; }
    fs::create_symlink(dir_ / "a.exr", dir_ / "soft.exr");
    fs::create_hard_link(dir_ / "a.exr", dir_ / "hard.exr");
    const std::string a = (dir_ / "a.exr").string();
    EXPECT_TRUE(same_file(a, a));
    EXPECT_TRUE(same_file(a, (dir_ / "sub" / ".." / "." / "a.exr").string()));
    EXPECT_TRUE(same_file(a, (dir_ / "soft.exr").string()));
    EXPECT_TRUE(same_file(a, (dir_ / "hard.exr").string()));
    EXPECT_FALSE(same_file(a, (dir_ / "b.exr").string()));
    // Files that do not exist yet: by their resolved paths.
    EXPECT_TRUE(same_file((dir_ / "new.exr").string(), (dir_ / "sub" / ".." / "new.exr").string()));
    EXPECT_FALSE(same_file((dir_ / "new.exr").string(), (dir_ / "other.exr").string()));
    EXPECT_FALSE(same_file(a, (dir_ / "new.exr").string()));
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
