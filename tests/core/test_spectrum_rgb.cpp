// SPDX-License-Identifier: GPL-3.0-or-later
// Spectra in scene files become the RGB Mitsuba 3's RGB variants give them.
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>
#include <vector>

#include "core/scene/spectrum_rgb.h"

namespace gdmlt {
namespace {

// Mitsuba 3's own cbox.xml (mitsuba-data scenes/cbox), its walls and light.
const std::string kWhite =
    "400:0.343, 404:0.445, 408:0.551, 412:0.624, 416:0.665, 420:0.687, 424:0.708, 428:0.723, "
    "432:0.715, 436:0.71, 440:0.745, 444:0.758, 448:0.739, 452:0.767, 456:0.777, 460:0.765, "
    "464:0.751, 468:0.745, 472:0.748, 476:0.729, 480:0.745, 484:0.757, 488:0.753, 492:0.75, "
    "496:0.746, 500:0.747, 504:0.735, 508:0.732, 512:0.739, 516:0.734, 520:0.725, 524:0.721, "
    "528:0.733, 532:0.725, 536:0.732, 540:0.743, 544:0.744, 548:0.748, 552:0.728, 556:0.716, "
    "560:0.733, 564:0.726, 568:0.713, 572:0.74, 576:0.754, 580:0.764, 584:0.752, 588:0.736, "
    "592:0.734, 596:0.741, 600:0.74, 604:0.732, 608:0.745, 612:0.755, 616:0.751, 620:0.744, "
    "624:0.731, 628:0.733, 632:0.744, 636:0.731, 640:0.712, 644:0.708, 648:0.729, 652:0.73, "
    "656:0.727, 660:0.707, 664:0.703, 668:0.729, 672:0.75, 676:0.76, 680:0.751, 684:0.739, "
    "688:0.724, 692:0.73, 696:0.74, 700:0.737";
const std::string kRed =
    "400:0.04, 404:0.046, 408:0.048, 412:0.053, 416:0.049, 420:0.05, 424:0.053, 428:0.055, "
    "432:0.057, 436:0.056, 440:0.059, 444:0.057, 448:0.061, 452:0.061, 456:0.06, 460:0.062, "
    "464:0.062, 468:0.062, 472:0.061, 476:0.062, 480:0.06, 484:0.059, 488:0.057, 492:0.058, "
    "496:0.058, 500:0.058, 504:0.056, 508:0.055, 512:0.056, 516:0.059, 520:0.057, 524:0.055, "
    "528:0.059, 532:0.059, 536:0.058, 540:0.059, 544:0.061, 548:0.061, 552:0.063, 556:0.063, "
    "560:0.067, 564:0.068, 568:0.072, 572:0.08, 576:0.09, 580:0.099, 584:0.124, 588:0.154, "
    "592:0.192, 596:0.255, 600:0.287, 604:0.349, 608:0.402, 612:0.443, 616:0.487, 620:0.513, "
    "624:0.558, 628:0.584, 632:0.62, 636:0.606, 640:0.609, 644:0.651, 648:0.612, 652:0.61, "
    "656:0.65, 660:0.638, 664:0.627, 668:0.62, 672:0.63, 676:0.628, 680:0.642, 684:0.639, "
    "688:0.657, 692:0.639, 696:0.635, 700:0.642";

void expect_rgb_near(const Rgb& got, const Rgb& expected, float relative) {
    for (int c = 0; c < 3; ++c)
        EXPECT_NEAR(got[c], expected[c], relative * std::abs(expected[c]))
            << "channel " << c << ": got (" << got.transpose() << "), expected ("
            << expected.transpose() << ")";
}

TEST(SpectrumRgb, CboxSpectraAreTheColoursMitsuba3Gives) {
    // Expected: mitsuba.spectrum_list_to_srgb of Mitsuba 3.9.1 (scalar_rgb), with the flags
    // its RGB variants pass (reflectance: bounded, D65; emitter: neither), and
    // mitsuba.xyz_to_srgb(1, 1, 1) for a uniform emitter. Mitsuba sums in single precision,
    // we in double: 1e-5 relative covers the rounding of a 1000-term float sum.
    const float tolerance = 1e-5f;
    expect_rgb_near(spectrum_text_to_rgb(kWhite, SpectrumUse::Reflectance),
                    Rgb(0.7350127696990967f, 0.735625147819519f, 0.7362642288208008f), tolerance);
    expect_rgb_near(spectrum_text_to_rgb(kRed, SpectrumUse::Reflectance),
                    Rgb(0.49132004380226135f, 0.04922797903418541f, 0.05092189460992813f),
                    tolerance);
    expect_rgb_near(
        spectrum_text_to_rgb("400:0.78, 500:0.78, 600:0.78, 700:0.78", SpectrumUse::Reflectance),
        Rgb(0.776367723941803f, 0.7798091173171997f, 0.7760289311408997f), tolerance);
    expect_rgb_near(spectrum_text_to_rgb("400:0, 500:8, 600:15.6, 700:18.4", SpectrumUse::Emission),
                    Rgb(20.7108211517334f, 10.854641914367676f, 2.771151065826416f), tolerance);
    expect_rgb_near(spectrum_text_to_rgb("2", SpectrumUse::Emission),
                    2.f * Rgb(1.204793930053711f, 0.948291003704071f, 0.9089160561561584f),
                    tolerance);
}

TEST(SpectrumRgb, FlatSpectraAreGreyOrTheWhiteOfTheirIlluminant) {
    // A flat reflectance over the visible range under D65 is grey of its value (the D65 white
    // point is sRGB's); a uniform reflectance is the value itself.
    const Rgb flat = spectrum_text_to_rgb("360:0.5, 830:0.5", SpectrumUse::Reflectance);
    expect_rgb_near(flat, Rgb::Constant(0.5f), 2e-3f);
    EXPECT_TRUE((spectrum_text_to_rgb(" 0.25 ", SpectrumUse::Reflectance) == 0.25f).all());
    EXPECT_TRUE((spectrum_text_to_rgb("3", SpectrumUse::Unbounded) == 3.f).all());
    // Unweighted, a flat unit spectrum has luminance 1 (the matching functions' scale).
    const RgbD emitted = spectrum_pairs_to_linear_srgb({360.0, 830.0}, {1.0, 1.0}, false);
    EXPECT_NEAR(0.2126 * emitted[0] + 0.7152 * emitted[1] + 0.0722 * emitted[2], 1.0, 2e-3);
}

TEST(SpectrumRgb, OutOfGamutColoursAreClampedAsMitsubaClampsThem) {
    // A narrow band at 520 nm is greener than sRGB can show: negative red and blue.
    bool clamped = false;
    const std::string band = "515:0, 520:1, 525:0";
    const Rgb reflectance = spectrum_text_to_rgb(band, SpectrumUse::Reflectance, &clamped);
    EXPECT_TRUE(clamped);
    EXPECT_EQ(reflectance[0], 0.f);
    EXPECT_EQ(reflectance[2], 0.f);
    const RgbD raw = spectrum_pairs_to_linear_srgb({515, 520, 525}, {0, 1, 0}, true);
    EXPECT_LT(raw[0], 0.0);
    EXPECT_NEAR(reflectance[1], raw[1], 1e-6 * raw[1]);
    // A reflectance above 1 is clamped to 1; an emitter's is not.
    const Rgb bright = spectrum_text_to_rgb("360:3, 830:3", SpectrumUse::Reflectance, &clamped);
    EXPECT_TRUE(clamped);
    EXPECT_TRUE((bright == 1.f).all()) << bright.transpose();
    const Rgb light = spectrum_text_to_rgb("360:3, 830:3", SpectrumUse::Emission, &clamped);
    EXPECT_FALSE(clamped);
    EXPECT_GT(light.minCoeff(), 2.f);
}

TEST(SpectrumRgb, MalformedSpectraAreErrorsNamingTheText) {
    for (const std::string bad : {"", "400:0.5", "400:0.5, 390:0.6", "400:0.5, 500", "400:x, 500:1",
                                  "abc", "400:0.5,, 500:1", "400:nan, 500:1"}) {
        try {
            spectrum_text_to_rgb(bad, SpectrumUse::Reflectance);
            ADD_FAILURE() << "accepted \"" << bad << "\"";
        } catch (const std::invalid_argument& e) {
            EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << e.what();
        }
    }
}

}  // namespace
}  // namespace gdmlt
