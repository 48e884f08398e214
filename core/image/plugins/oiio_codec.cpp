// SPDX-License-Identifier: GPL-3.0-or-later
// The OpenImageIO codec, a module loaded at run time (core/image/oiio_codec.h says why): reads
// any image OpenImageIO understands into a float buffer the caller provides. C entry points
// only, no exception crosses them.
#include "core/image/oiio_codec.h"

#include <OpenImageIO/imageio.h>

#include <cstddef>
#include <cstdio>
#include <exception>
#include <string>

namespace {

void set_error(char* error, std::size_t error_size, const std::string& message) {
    if (error && error_size > 0) std::snprintf(error, error_size, "%s", message.c_str());
}

}  // namespace

extern "C" __attribute__((visibility("default"))) int gdmlt_oiio_read_image(
    const char* path, gdmlt_oiio_allocate allocate, void* user, int* integer_format, char* error,
    std::size_t error_size) {
    try {
        auto in = OIIO::ImageInput::open(path);
        if (!in) {
            set_error(error, error_size, OIIO::geterror());
            return 1;
        }
        const OIIO::ImageSpec& spec = in->spec();
        if (integer_format) *integer_format = spec.format.is_floating_point() ? 0 : 1;
        float* pixels = allocate(user, spec.width, spec.height, spec.nchannels);
        if (!pixels) {
            set_error(error, error_size, "no memory for the pixels");
            return 1;
        }
        if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, pixels)) {
            set_error(error, error_size, in->geterror());
            return 1;
        }
        in->close();
        return 0;
    } catch (const std::exception& e) {
        set_error(error, error_size, e.what());
        return 1;
    }
}
