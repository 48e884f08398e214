// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Command-line checks CLI11 lacks. Its PositiveNumber and Range compare with < and >, which
// NaN passes: `--time nan` used to be ignored and `--alpha nan` found only after the render.
#include <CLI/CLI.hpp>
#include <cmath>
#include <string>

namespace gdmlt {

/// Accepts a number only if it is finite (no nan, inf or overflow such as 1e999).
inline CLI::Validator finite_number() {
    return CLI::Validator(
        [](std::string& text) -> std::string {
            double value = 0.0;
            if (!CLI::detail::lexical_cast(text, value)) return "'" + text + "' is not a number";
            if (!std::isfinite(value)) return "'" + text + "' is not a finite number";
            return "";
        },
        "FINITE");
}

}  // namespace gdmlt
