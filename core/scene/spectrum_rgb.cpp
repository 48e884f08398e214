// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/scene/spectrum_rgb.h"

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdlib>

namespace gdmlt {
namespace {

// CIE tables at 5 nm from 360 to 830 nm (95 samples): the CIE 1931 2-degree standard observer
// (CIE 018:2019) and the CIE standard illuminant D65 (relative spectral power, 100 at 560 nm;
// ISO 11664-2). Published data, as tabulated by the CIE.
constexpr int kCieSamples = 95;
constexpr double kCieMinNm = 360.0, kCieMaxNm = 830.0;
constexpr std::array<double, kCieSamples> kCie1931X = {
    0.0001299,    0.0002321,    0.0004149,    0.0007416,    0.001368,     0.002236,
    0.004243,     0.00765,      0.01431,      0.02319,      0.04351,      0.07763,
    0.13438,      0.21477,      0.2839,       0.3285,       0.34828,      0.34806,
    0.3362,       0.3187,       0.2908,       0.2511,       0.19536,      0.1421,
    0.09564,      0.05795001,   0.03201,      0.0147,       0.0049,       0.0024,
    0.0093,       0.0291,       0.06327,      0.1096,       0.1655,       0.2257499,
    0.2904,       0.3597,       0.4334499,    0.5120501,    0.5945,       0.6784,
    0.7621,       0.8425,       0.9163,       0.9786,       1.0263,       1.0567,
    1.0622,       1.0456,       1.0026,       0.9384,       0.8544499,    0.7514,
    0.6424,       0.5419,       0.4479,       0.3608,       0.2835,       0.2187,
    0.1649,       0.1212,       0.0874,       0.0636,       0.04677,      0.0329,
    0.0227,       0.01584,      0.01135916,   0.008110916,  0.005790346,  0.004109457,
    0.002899327,  0.00204919,   0.001439971,  0.0009999493, 0.0006900786, 0.0004760213,
    0.0003323011, 0.0002348261, 0.0001661505, 0.000117413,  8.307527e-05, 5.870652e-05,
    4.150994e-05, 2.935326e-05, 2.067383e-05, 1.455977e-05, 1.025398e-05, 7.221456e-06,
    5.085868e-06, 3.581652e-06, 2.522525e-06, 1.776509e-06, 1.251141e-06,
};
constexpr std::array<double, kCieSamples> kCie1931Y = {
    3.917e-06,  6.965e-06,  1.239e-05,  2.202e-05,  3.9e-05,    6.4e-05,    0.00012,    0.000217,
    0.000396,   0.00064,    0.00121,    0.00218,    0.004,      0.0073,     0.0116,     0.01684,
    0.023,      0.0298,     0.038,      0.048,      0.06,       0.0739,     0.09098,    0.1126,
    0.13902,    0.1693,     0.20802,    0.2586,     0.323,      0.4073,     0.503,      0.6082,
    0.71,       0.7932,     0.862,      0.9148501,  0.954,      0.9803,     0.9949501,  1,
    0.995,      0.9786,     0.952,      0.9154,     0.87,       0.8163,     0.757,      0.6949,
    0.631,      0.5668,     0.503,      0.4412,     0.381,      0.321,      0.265,      0.217,
    0.175,      0.1382,     0.107,      0.0816,     0.061,      0.04458,    0.032,      0.0232,
    0.017,      0.01192,    0.00821,    0.005723,   0.004102,   0.002929,   0.002091,   0.001484,
    0.001047,   0.00074,    0.00052,    0.0003611,  0.0002492,  0.0001719,  0.00012,    8.48e-05,
    6e-05,      4.24e-05,   3e-05,      2.12e-05,   1.499e-05,  1.06e-05,   7.4657e-06, 5.2578e-06,
    3.7029e-06, 2.6078e-06, 1.8366e-06, 1.2934e-06, 9.1093e-07, 6.4153e-07, 4.5181e-07,
};
constexpr std::array<double, kCieSamples> kCie1931Z = {
    0.0006061,
    0.001086,
    0.001946,
    0.003486,
    0.006450001,
    0.01054999,
    0.02005001,
    0.03621,
    0.06785001,
    0.1102,
    0.2074,
    0.3713,
    0.6456,
    1.03905,
    1.3856,
    1.62296,
    1.74706,
    1.7826,
    1.77211,
    1.7441,
    1.6692,
    1.5281,
    1.28764,
    1.0419,
    0.8129501,
    0.6162,
    0.46518,
    0.3533,
    0.272,
    0.2123,
    0.1582,
    0.1117,
    0.07824999,
    0.05725001,
    0.04216,
    0.02984,
    0.0203,
    0.0134,
    0.008749999,
    0.005749999,
    0.0039,
    0.002749999,
    0.0021,
    0.0018,
    0.001650001,
    0.0014,
    0.0011,
    0.001,
    0.0008,
    0.0006,
    0.00034,
    0.00024,
    0.00019,
    0.0001,
    4.999999e-05,
    3e-05,
    2e-05,
    1e-05,
    2.117582e-22,
    0,
    0,
    0,
    0,
    0,
    0,
    0,
    0,
    0,
    0,
    0,
    0,
    0,
    0,
    0,
    0,
    0,
    0,
    0,
    0,
    0,
    0,
    0,
    0,
    0,
    0,
    0,
    0,
    0,
    0,
    0,
    0,
    0,
    0,
    0,
    0,
};
constexpr std::array<double, kCieSamples> kD65 = {
    46.6383, 49.3637, 52.0891, 51.0323, 49.9755, 52.3118, 54.6482, 68.7015, 82.7549, 87.1204,
    91.486,  92.4589, 93.4318, 90.057,  86.6823, 95.7736, 104.865, 110.936, 117.008, 117.41,
    117.812, 116.336, 114.861, 115.392, 115.923, 112.367, 108.811, 109.082, 109.354, 108.578,
    107.802, 106.296, 104.79,  106.239, 107.689, 106.047, 104.405, 104.225, 104.046, 102.023,
    100,     98.1671, 96.3342, 96.0611, 95.788,  92.2368, 88.6856, 89.3459, 90.0062, 89.8026,
    89.5991, 88.6489, 87.6987, 85.4936, 83.2886, 83.4939, 83.6992, 81.863,  80.0268, 80.1207,
    80.2146, 81.2462, 82.2778, 80.281,  78.2842, 74.0027, 69.7213, 70.6652, 71.6091, 72.979,
    74.349,  67.9765, 61.604,  65.7448, 69.8856, 72.4863, 75.087,  69.3398, 63.5927, 55.0054,
    46.4182, 56.6118, 66.8054, 65.0941, 63.3828, 63.8434, 64.304,  61.8779, 59.4519, 55.7054,
    51.959,  54.6998, 57.4406, 58.8765, 60.3125,
};

/// Linear interpolation of a 5 nm table at `nm` (inside [360, 830]).
double table_at(const std::array<double, kCieSamples>& table, double nm) {
    const double t = (nm - kCieMinNm) * ((kCieSamples - 1) / (kCieMaxNm - kCieMinNm));
    const int i0 = std::clamp(static_cast<int>(t), 0, kCieSamples - 2);
    const double w1 = t - i0;
    return (1.0 - w1) * table[static_cast<std::size_t>(i0)] +
           w1 * table[static_cast<std::size_t>(i0) + 1];
}

/// The Riemann sum over [360, 830] nm of `f` times the three matching functions, with
/// Mitsuba 3's 1000 wavelengths, step and normalisations: Y of a flat unit spectrum is 1 with
/// the curves scaled by 1 / 106.7502594, and D65 is scaled by 1 / 98.99741752 (Mitsuba's
/// MI_CIE_Y_NORMALIZATION and MI_CIE_D65_NORMALIZATION; the sums computed here come within
/// 0.1% of them, which is what the colours would move by).
template <typename Function>
RgbD integrate_xyz(Function f, bool d65_weighted) {
    constexpr int kSteps = 1000;
    constexpr double kYNormalisation = 1.0 / 106.7502593994140625;
    constexpr double kD65Normalisation = 1.0 / 98.99741751876255;
    RgbD xyz = RgbD::Zero();
    for (int i = 0; i < kSteps; ++i) {
        const double nm =
            kCieMinNm + (i / static_cast<double>(kSteps - 1)) * (kCieMaxNm - kCieMinNm);
        const double v = f(nm);
        if (v == 0.0) continue;
        const double weight = v * (d65_weighted ? table_at(kD65, nm) * kD65Normalisation : 1.0);
        xyz += weight *
               RgbD(table_at(kCie1931X, nm), table_at(kCie1931Y, nm), table_at(kCie1931Z, nm));
    }
    return xyz * ((kCieMaxNm - kCieMinNm) * kYNormalisation / kSteps);
}

[[noreturn]] void bad(const std::string& text, const std::string& why) {
    throw std::invalid_argument("bad spectrum \"" + text + "\": " + why);
}

double parse_number(const std::string& token, const std::string& text) {
    const char* begin = token.c_str();
    char* end = nullptr;
    errno = 0;
    const double v = std::strtod(begin, &end);
    if (end == begin || *end != '\0' || errno == ERANGE || !std::isfinite(v))
        bad(text, "\"" + token + "\" is not a number");
    return v;
}

std::string trimmed(const std::string& s) {
    const auto first = s.find_first_not_of(" \t\r\n");
    if (first == std::string::npos) return {};
    const auto last = s.find_last_not_of(" \t\r\n");
    return s.substr(first, last - first + 1);
}

}  // namespace

RgbD xyz_to_linear_srgb(const RgbD& xyz) {
    // The sRGB primaries and D65 white (IEC 61966-2-1), to the digits Mitsuba 3 writes.
    return {3.240479 * xyz[0] - 1.537150 * xyz[1] - 0.498535 * xyz[2],
            -0.969256 * xyz[0] + 1.875991 * xyz[1] + 0.041556 * xyz[2],
            0.055648 * xyz[0] - 0.204043 * xyz[1] + 1.057311 * xyz[2]};
}

RgbD spectrum_pairs_to_linear_srgb(const std::vector<double>& wavelengths_nm,
                                   const std::vector<double>& values, bool d65_weighted) {
    const std::size_t n = wavelengths_nm.size();
    const RgbD xyz = integrate_xyz(
        [&](double nm) {
            if (nm < wavelengths_nm.front() || nm > wavelengths_nm.back()) return 0.0;
            // The last given wavelength not above nm (the interval's start).
            const auto upper = std::upper_bound(wavelengths_nm.begin(), wavelengths_nm.end(), nm);
            const std::size_t i = std::min<std::size_t>(
                static_cast<std::size_t>(upper - wavelengths_nm.begin()) - 1, n - 2);
            const double w0 = wavelengths_nm[i], w1 = wavelengths_nm[i + 1];
            return ((w1 - nm) * values[i] + (nm - w0) * values[i + 1]) / (w1 - w0);
        },
        d65_weighted);
    return xyz_to_linear_srgb(xyz);
}

Rgb spectrum_text_to_rgb(const std::string& text, SpectrumUse use, bool* clamped) {
    if (clamped) *clamped = false;
    const std::string body = trimmed(text);
    if (body.empty()) bad(text, "empty");
    if (body.find(':') == std::string::npos) {
        const double v = parse_number(body, text);
        if (use != SpectrumUse::Emission) return Rgb::Constant(static_cast<float>(v));
        return (v * xyz_to_linear_srgb(RgbD::Ones())).cast<float>();
    }
    std::vector<double> wavelengths, values;
    std::size_t start = 0;
    while (start <= body.size()) {
        std::size_t comma = body.find(',', start);
        if (comma == std::string::npos) comma = body.size();
        const std::string pair = trimmed(body.substr(start, comma - start));
        const std::size_t colon = pair.find(':');
        if (colon == std::string::npos) bad(text, "\"" + pair + "\" is not wavelength:value");
        const double nm = parse_number(trimmed(pair.substr(0, colon)), text);
        const double value = parse_number(trimmed(pair.substr(colon + 1)), text);
        if (!wavelengths.empty() && !(nm > wavelengths.back()))
            bad(text, "the wavelengths must increase");
        wavelengths.push_back(nm);
        values.push_back(value);
        start = comma + 1;
    }
    if (wavelengths.size() < 2) bad(text, "at least two wavelength:value pairs are needed");
    const RgbD rgb =
        spectrum_pairs_to_linear_srgb(wavelengths, values, use != SpectrumUse::Emission);
    RgbD limited = rgb.max(0.0);
    if (use == SpectrumUse::Reflectance) limited = limited.min(1.0);
    if (clamped) *clamped = (limited != rgb).any();
    return limited.cast<float>();
}

}  // namespace gdmlt
