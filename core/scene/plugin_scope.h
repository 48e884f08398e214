// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Mitsuba 3 plugins that gdmlt does not implement by design: participating media, polarisation,
// hair, curves, SDF grids and the Disney principled BSDFs. A scene that names one ends with an
// input error saying so (exit 2), rather than "unknown", so that a user can tell a feature left
// out from a typing error or a plugin not written yet.
#include <optional>
#include <string>
#include <string_view>

namespace gdmlt {

/// Why the plugin `type` of element `tag` (Mitsuba's tag names: bsdf, shape, integrator,
/// medium, phase, volume, emitter, sensor, texture) is outside gdmlt's scope, or nullopt when
/// it is not one of those plugins.
std::optional<std::string_view> out_of_scope_reason(std::string_view tag, std::string_view type);

/// The error message for such a plugin: "<tag> '<type>' is not supported: <reason> ...".
std::string out_of_scope_message(std::string_view tag, std::string_view type,
                                 std::string_view reason);

}  // namespace gdmlt
