// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// `gdmlt reconstruct raw.exr --method l1|l2|cv --alpha 0.2 [--iterations N] -o final.exr`:
// reads the layers a gradient-domain render writes (core/image/gradient_layers.h: "primal", "dx",
// "dy", optional "very_direct", "sample_count" and the variance layers), reconstructs, writes the
// EXR and a PNG preview beside it.
#include <CLI/CLI.hpp>

namespace gdmlt {

/// Registers the `reconstruct` subcommand. Its callback runs during app.parse and sets
/// `exit_code` (0 ok, 2 input error such as a missing file or layer, 1 internal error); it
/// reports errors itself and never throws.
void add_reconstruct_command(CLI::App& app, int& exit_code);

}  // namespace gdmlt
