// SPDX-License-Identifier: GPL-3.0-or-later
#include "reconstruct/reconstruct.h"

#include <stdexcept>

#include "reconstruct/coarse_correction.h"

namespace gdmlt::reconstruct {

namespace {

ReconstructResult solve(const ReconstructInput& input, const ReconstructConfig& config) {
    switch (config.method) {
        case Method::l2:
            return solve_l2(input, config);
        case Method::l1:
            return solve_l1(input, config);
        case Method::cv:
            return solve_cv(input, config);
    }
    return solve_l1(input, config);
}

}  // namespace

ReconstructResult reconstruct(const ReconstructInput& input, const ReconstructConfig& config) {
    if (config.coarse_radius < 0) throw std::invalid_argument("reconstruct: coarse_radius < 0");
    ReconstructResult result = solve(input, config);
    restore_coarse_scales(result.image, input.primal, config.coarse_radius);
    return result;
}

ReconstructResult reconstruct_buffers(const GradientBuffers& buffers,
                                      const ReconstructConfig& config) {
    ReconstructResult result = reconstruct(make_reconstruct_input(buffers), config);
    const Image& direct = buffers.very_direct;
    if (direct.pixels.empty()) return result;
    Image& image = result.image;
    if (direct.width != image.width || direct.height != image.height || direct.channels != 3 ||
        image.channels != 3)
        throw std::invalid_argument("very_direct layer: size differs from the primal's");
    for (std::size_t i = 0; i < image.pixels.size(); ++i) image.pixels[i] += direct.pixels[i];
    return result;
}

}  // namespace gdmlt::reconstruct
