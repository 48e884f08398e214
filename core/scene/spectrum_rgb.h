// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Spectra written in scene files (<spectrum value="0.5"/>, <spectrum value="400:0.34,
// 404:0.45, ..."/>) as the RGB that Mitsuba 3's RGB variants use for them, so that a scene
// written for its spectral variants (its own cbox.xml) renders here as there.
//
// Mitsuba 3 (Properties::get_texture in its RGB modes):
//  - a uniform spectrum v is grey v, except on an emitter, where it is v * M (1, 1, 1): the
//    equal-energy white seen in sRGB (D65 white), a slightly purple colour, so that RGB and
//    spectral renders agree;
//  - wavelength:value pairs are interpolated linearly between the given wavelengths (zero
//    outside them) and integrated against the CIE 1931 colour matching functions by a midpoint-
//    free Riemann sum of 1000 wavelengths evenly spaced over [360, 830] nm, a reflectance
//    weighted by the D65 illuminant (so that a flat reflectance 1 is white), an emitter not;
//    XYZ goes to linear sRGB with M below. A reflectance is clamped to [0, 1], anything else to
//    >= 0.
#include <stdexcept>
#include <string>
#include <vector>

#include "core/math/types.h"

namespace gdmlt {

enum class SpectrumUse {
    Reflectance,  // bounded to [0, 1], D65-weighted (reflectances, albedos)
    Unbounded,    // >= 0, D65-weighted (indices of refraction, extinction)
    Emission,     // >= 0, not weighted (radiance, intensity, irradiance)
};

/// "v" or "lambda:value, lambda:value, ..." (wavelengths in nm, increasing, at least two
/// pairs) as linear sRGB for `use`. Throws std::invalid_argument with a message on bad text.
/// `clamped`, when given, is set when the colour was out of gamut and clamped (Mitsuba warns).
Rgb spectrum_text_to_rgb(const std::string& text, SpectrumUse use, bool* clamped = nullptr);

/// The integration above for wavelength:value pairs (sizes equal, >= 2, wavelengths
/// increasing), before clamping: linear sRGB.
RgbD spectrum_pairs_to_linear_srgb(const std::vector<double>& wavelengths_nm,
                                   const std::vector<double>& values, bool d65_weighted);

/// CIE 1931 XYZ -> linear sRGB (D65 white): the matrix Mitsuba 3 uses.
RgbD xyz_to_linear_srgb(const RgbD& xyz);

/// Linear sRGB (Rec. 709) -> CIE 1931 XYZ, Mitsuba 3's srgb_to_xyz matrix (the inverse of the
/// above): the `moment` integrator's channels. Inline: the film calls it once per sample.
inline Vec3f linear_srgb_to_xyz(const Rgb& rgb) {
    return {0.412453f * rgb[0] + 0.357580f * rgb[1] + 0.180423f * rgb[2],
            0.212671f * rgb[0] + 0.715160f * rgb[1] + 0.072169f * rgb[2],
            0.019334f * rgb[0] + 0.119193f * rgb[1] + 0.950227f * rgb[2]};
}

}  // namespace gdmlt
