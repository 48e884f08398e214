// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// OpenImageIO, loaded when an image needs it. Debian's libOpenImageIO depends on about 250
// shared libraries (codecs, DICOM, OpenVDB, FFmpeg...), and relocating them took 0.33 s of
// every gdmlt process's start-up, the same as a whole render of a small scene (callgrind: 0.9 G
// instructions in the dynamic linker against 0.6 G for a 96^2 render; `gdmlt --help` 0.35 s).
// So the executable does not link it: the one function that needs it, reading images in
// formats other than EXR (PNG, JPEG, HDR... textures), lives in the module
// libgdmlt_oiio_codec.so (core/image/plugins/oiio_codec.cpp), which image_io.cpp opens with
// dlopen on first use. EXR goes through OpenEXR, and PNG previews are written with libpng.
#include <cstddef>

extern "C" {
/// Asked for a buffer of width x height x channels floats; returns null when it cannot give one.
using gdmlt_oiio_allocate = float* (*)(void* user, int width, int height, int channels);
/// Reads the image at `path` as floats into the buffer `allocate` gives, channels interleaved;
/// `integer_format` receives 1 for integer pixel formats. Returns 0, or 1 with a message in
/// `error` (at most `error_size` bytes, terminated).
using gdmlt_oiio_read_image_fn = int (*)(const char* path, gdmlt_oiio_allocate allocate, void* user,
                                         int* integer_format, char* error, std::size_t error_size);
int gdmlt_oiio_read_image(const char* path, gdmlt_oiio_allocate allocate, void* user,
                          int* integer_format, char* error, std::size_t error_size);
}
