// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Image files. OpenEXR / OpenImageIO appear only in image_io.cpp.
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/image/image.h"

namespace gdmlt {

/// An output file could not be written (full disk, no permission, not a regular file...); the
/// message names the file and the reason. Distinct from programming errors, which the CLI
/// reports as internal.
struct OutputError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

/// Throws OutputError unless `path` can become an output file: it must not exist as anything
/// but a regular file (a device, FIFO or directory is never replaced: as root, -o /dev/null
/// once replaced the device node), and its directory, or the nearest existing ancestor that
/// would hold it, must be writable. `what` names the option in the message.
void check_output_path(const std::string& path, const std::string& what);

/// Whether two paths name the same file: the same inode when both exist (so hard links and
/// symbolic links count), else the same path once symbolic links, "." and ".." are resolved.
/// Outputs must not replace the scene, the input or each other.
bool same_file(const std::string& a, const std::string& b);

/// Writes `text` to `path` through a temporary file renamed over it; the temporary is removed
/// on failure. Throws OutputError.
void write_text_file(const std::string& path, const std::string& text);

/// One layer of a multi-layer EXR. The main image has an empty name and channels "R","G","B";
/// a named layer "primal" with channels {"R","G","B"} is stored as "primal.R", "primal.G", ...
struct ExrLayer {
    std::string name;
    std::vector<std::string> channel_names;  // size == image.channels
    Image image;
};

/// String attributes stored in the EXR header (effective config, seed, version, partial flag).
using ExrAttributes = std::map<std::string, std::string>;

/// Writes a multi-layer float32 EXR. All layers must have the same size. Writes to a temporary
/// file in the same directory and renames it over `path`, so a crash never leaves half a file.
/// Throws OutputError on I/O failure.
void write_exr(const std::string& path, const std::vector<ExrLayer>& layers,
               const ExrAttributes& attributes = {});

/// Reads every channel of an EXR, grouped into layers by the prefix before the last '.'.
/// Channels without a prefix form the layer with the empty name. Optionally returns the
/// string attributes of the header. Throws InputError (core/scene/scene_desc.h) naming the
/// file when it cannot be read.
std::vector<ExrLayer> read_exr(const std::string& path, ExrAttributes* attributes = nullptr);

/// Writes an 8-bit sRGB PNG preview of a linear RGB image, scaled by 2^exposure_stops, clamped.
/// Same temporary-file-and-rename rule.
void write_png_srgb(const std::string& path, const Image& rgb, float exposure_stops = 0.f);

/// Files that replace their paths together or not at all: each is written to a temporary file
/// beside its path, and only when every one has been written does commit() rename them over
/// their paths (a new EXR beside the previous render's statistics would mislead whoever reads
/// them together). Every write is a checked system call: libpng and OpenEXR's destructor do not
/// report all failures, and a full disk once left an empty EXR behind. A failure throws
/// OutputError naming the file and the system's reason ("File too large", "No space left on
/// device"); the destructor removes every temporary not yet renamed.
class OutputFiles {
  public:
    OutputFiles() = default;
    ~OutputFiles();
    OutputFiles(const OutputFiles&) = delete;
    OutputFiles& operator=(const OutputFiles&) = delete;

    /// Multi-layer float32 EXR (see write_exr).
    void add_exr(const std::string& path, const std::vector<ExrLayer>& layers,
                 const ExrAttributes& attributes = {});
    /// 8-bit sRGB PNG preview (see write_png_srgb).
    void add_png_srgb(const std::string& path, const Image& rgb, float exposure_stops = 0.f);
    void add_text(const std::string& path, const std::string& text);
    /// Renames every file over its path, in the order added. Throws OutputError (a rename fails
    /// only in a directory that changed under us; files renamed before it stay).
    void commit();

  private:
    struct Staged {
        std::string path, temporary;
    };
    std::vector<Staged> staged_;
};

/// Reads any image OpenImageIO understands (EXR, HDR, PNG, JPEG...) as float RGB(A) with the
/// file's channel count; 8-bit sRGB files are returned as stored (no linearisation here).
Image read_image(const std::string& path);

/// What read_image found about a file's encoding.
struct ImageFileInfo {
    /// Integer pixel format (8/16-bit PNG, JPEG, TIFF...): values are display-encoded (sRGB)
    /// by convention; float formats (EXR, HDR) are linear.
    bool integer_format = false;
};
/// read_image, also reporting the file's encoding (for texture loading: bitmaps linearise
/// integer formats unless asked not to, as Mitsuba's `raw=false` does).
Image read_image(const std::string& path, ImageFileInfo* info);

/// sRGB transfer function (IEC 61966-2-1) and its inverse, on one channel.
float srgb_to_linear(float v);
float linear_to_srgb(float v);

}  // namespace gdmlt
