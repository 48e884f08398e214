// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/scene/plugin_scope.h"

#include <array>

namespace gdmlt {
namespace {

struct OutOfScope {
    std::string_view tag;
    std::string_view type;  // empty: every plugin of the tag
    std::string_view reason;
};

constexpr std::string_view kMedia = "participating media are outside gdmlt's scope";
constexpr std::string_view kPolarisation = "polarisation is outside gdmlt's scope";

// Mitsuba 3.x plugin names (its documentation's plugin reference).
constexpr std::array kOutOfScope = {
    OutOfScope{"medium", "", kMedia},
    OutOfScope{"phase", "", kMedia},
    OutOfScope{"volume", "", kMedia},
    OutOfScope{"integrator", "volpath", kMedia},
    OutOfScope{"integrator", "volpathmis", kMedia},
    OutOfScope{"integrator", "prbvolpath", kMedia},
    OutOfScope{"integrator", "stokes", kPolarisation},
    OutOfScope{"bsdf", "pplastic", kPolarisation},
    OutOfScope{"bsdf", "polarizer", kPolarisation},
    OutOfScope{"bsdf", "measured_polarized", kPolarisation},
    OutOfScope{"bsdf", "retarder", kPolarisation},
    OutOfScope{"bsdf", "circular", kPolarisation},
    OutOfScope{"bsdf", "hair", "hair fibres are outside gdmlt's scope"},
    OutOfScope{"bsdf", "principled", "the Disney principled BSDFs are outside gdmlt's scope"},
    OutOfScope{"bsdf", "principledthin", "the Disney principled BSDFs are outside gdmlt's scope"},
    OutOfScope{"shape", "linearcurve", "curves are outside gdmlt's scope"},
    OutOfScope{"shape", "bsplinecurve", "curves are outside gdmlt's scope"},
    OutOfScope{"shape", "sdfgrid", "SDF grids are outside gdmlt's scope"},
};

}  // namespace

std::optional<std::string_view> out_of_scope_reason(std::string_view tag, std::string_view type) {
    for (const OutOfScope& o : kOutOfScope)
        if (o.tag == tag && (o.type.empty() || o.type == type)) return o.reason;
    return std::nullopt;
}

std::string out_of_scope_message(std::string_view tag, std::string_view type,
                                 std::string_view reason) {
    // Appended piece by piece: GCC 12 warns (-Wrestrict, a false positive) on the
    // operator+ chain of string_views made strings.
    std::string message = "<";
    message.append(tag);
    if (!type.empty()) message.append(" type=\"").append(type).append("\"");
    message.append("> is not supported: ").append(reason);
    return message;
}

}  // namespace gdmlt
