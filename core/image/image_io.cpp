// SPDX-License-Identifier: GPL-3.0-or-later
// Image files.
//
// EXR goes through OpenEXR 3.1 directly rather than through OpenImageIO: we need exact control of
// the channel names of every layer ("primal.R", ...), float32 storage, ZIP compression and
// arbitrary string attributes in the header, and OpenEXR's FrameBuffer lets us write straight from
// our interleaved buffers (xStride/yStride) without a copy. OpenImageIO would rename or reorder
// channels and attributes in ways we would have to undo. PNG previews are encoded by libpng;
// images in other formats are read through OpenImageIO, loaded only then (core/image/oiio_codec.h
// says why).
#include "core/image/image_io.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIO.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <dlfcn.h>
#include <fcntl.h>
#include <png.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <system_error>

#include "core/image/oiio_codec.h"
#include "core/scene/scene_desc.h"

namespace gdmlt {
namespace {

namespace fs = std::filesystem;

/// A temporary path beside `path` (same directory, so rename is atomic on POSIX), unique per
/// process and call. Also creates the parent directory when missing.
fs::path temp_path_beside(const std::string& path) {
    static std::atomic<unsigned> counter{0};
    const fs::path target(path);
    const fs::path parent = target.parent_path();
    if (!parent.empty()) {
        std::error_code ec;
        fs::create_directories(parent, ec);
        if (ec)
            throw OutputError("cannot create directory '" + parent.string() + "': " + ec.message());
    }
    // Keep the extension last, so that a tool can tell the format from it.
    // Built with appends: GCC 12 gives a false -Wrestrict on `"." + std::string` at -O2.
    std::string name(1, '.');
    name.append(target.stem().string());
    name.append(".tmp");
    name.append(std::to_string(::getpid()));
    name.push_back('_');
    name.append(std::to_string(counter.fetch_add(1)));
    name.append(target.extension().string());
    fs::path tmp = target;
    tmp.replace_filename(name);
    return tmp;
}

/// A new file written through checked system calls. The first failure is remembered with its
/// errno rather than thrown at once: OpenEXR writes its line offset table in OutputFile's
/// destructor and swallows any exception there, so only finish() reports.
class CheckedFile {
  public:
    CheckedFile(const fs::path& temporary, const std::string& path) : path_(path) {
        fd_ = ::open(temporary.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
        if (fd_ < 0) error_ = errno;
    }
    ~CheckedFile() {
        if (fd_ >= 0) ::close(fd_);
    }
    CheckedFile(const CheckedFile&) = delete;
    CheckedFile& operator=(const CheckedFile&) = delete;

    void write(const char* data, std::size_t size) {
        while (error_ == 0 && size > 0) {
            const ssize_t n = ::write(fd_, data, size);
            if (n < 0) {
                if (errno != EINTR) error_ = errno;
                continue;
            }
            data += n;
            size -= static_cast<std::size_t>(n);
        }
    }
    void seek(std::uint64_t position) {
        if (error_ == 0 && ::lseek(fd_, static_cast<off_t>(position), SEEK_SET) < 0) error_ = errno;
    }
    bool failed() const { return error_ != 0; }
    /// Closes the file; throws OutputError naming the path and the first failure's reason.
    void finish() {
        if (fd_ >= 0 && ::close(fd_) != 0 && error_ == 0) error_ = errno;
        fd_ = -1;
        if (error_ != 0)
            throw OutputError("cannot write '" + path_ + "': " + std::strerror(error_));
    }

  private:
    std::string path_;
    int fd_ = -1;
    int error_ = 0;
};

/// OpenEXR's output stream on a CheckedFile.
class ExrFileStream final : public Imf::OStream {
  public:
    ExrFileStream(CheckedFile& file, const char* name) : Imf::OStream(name), file_(file) {}
    void write(const char c[], int n) override {
        file_.write(c, static_cast<std::size_t>(n));
        position_ += static_cast<std::uint64_t>(n);
    }
    std::uint64_t tellp() override { return position_; }
    void seekp(std::uint64_t position) override {
        file_.seek(position);
        position_ = position;
    }

  private:
    CheckedFile& file_;
    std::uint64_t position_ = 0;
};

std::string full_channel_name(const ExrLayer& layer, std::size_t c) {
    return layer.name.empty() ? layer.channel_names[c] : layer.name + "." + layer.channel_names[c];
}

/// Channels come back from OpenEXR sorted by name; restore the conventional order R,G,B,A then
/// X,Y,Z, then the rest alphabetically, so a layer written as R,G,B reads back as R,G,B.
int channel_rank(const std::string& c) {
    static const char* const order[] = {"R", "G", "B", "A", "X", "Y", "Z"};
    for (int i = 0; i < 7; ++i)
        if (c == order[i]) return i;
    return 7;
}

/// The OpenImageIO codec's read function, from the module loaded on the first call (see
/// core/image/oiio_codec.h). Looked for at $GDMLT_OIIO_CODEC, beside the executable, in
/// ../lib/gdmlt from it, then where the build put it. Throws InputError naming `image_path`
/// and the places tried when it cannot be loaded.
gdmlt_oiio_read_image_fn oiio_codec(const std::string& image_path) {
    struct Loaded {
        gdmlt_oiio_read_image_fn read = nullptr;
        std::string problem;
    };
    static const Loaded loaded = [] {
        Loaded l;
        std::vector<std::string> candidates;
        if (const char* env = std::getenv("GDMLT_OIIO_CODEC"); env && *env)
            candidates.emplace_back(env);
        std::error_code ec;
        const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
        const char* const name = "libgdmlt_oiio_codec.so";
        if (!ec) {
            candidates.push_back((exe.parent_path() / name).string());
            candidates.push_back((exe.parent_path() / ".." / "lib" / "gdmlt" / name).string());
        }
        candidates.emplace_back(GDMLT_OIIO_CODEC_BUILD_PATH);
        for (const std::string& candidate : candidates) {
            if (!fs::exists(candidate, ec)) {
                l.problem += (l.problem.empty() ? "" : ", ") + candidate + " (absent)";
                continue;
            }
            void* handle = ::dlopen(candidate.c_str(), RTLD_NOW | RTLD_LOCAL);
            void* symbol = handle ? ::dlsym(handle, "gdmlt_oiio_read_image") : nullptr;
            if (symbol) {
                l.read = reinterpret_cast<gdmlt_oiio_read_image_fn>(symbol);
                return l;
            }
            const char* why = ::dlerror();
            l.problem += (l.problem.empty() ? "" : ", ") + candidate + " (" +
                         (why ? why : "no gdmlt_oiio_read_image") + ")";
        }
        return l;
    }();
    if (!loaded.read)
        throw InputError(image_path +
                         ": cannot read image: the OpenImageIO codec module is missing: tried " +
                         loaded.problem);
    return loaded.read;
}

/// Reads an EXR whose channels are R, G, B (and A) or Y, without layers, the way OpenImageIO
/// would (in that order, float); returns false for any other EXR and for files that are not EXR
/// (by their magic number), which then go to OpenImageIO.
bool read_plain_exr(const std::string& path, Image& image) {
    {
        std::ifstream in(path, std::ios::binary);
        unsigned char magic[4] = {};
        if (!in.read(reinterpret_cast<char*>(magic), 4) ||
            !(magic[0] == 0x76 && magic[1] == 0x2f && magic[2] == 0x31 && magic[3] == 0x01))
            return false;
    }
    std::vector<ExrLayer> layers;
    try {
        layers = read_exr(path);
    } catch (const InputError&) {
        return false;  // OpenImageIO says what is wrong with it
    }
    if (layers.size() != 1 || !layers.front().name.empty()) return false;
    std::string channels;
    for (const std::string& c : layers.front().channel_names) channels += c + ",";
    // (read_exr puts A before Y, so a Y and A image is left to OpenImageIO's order.)
    if (channels != "R,G,B," && channels != "R,G,B,A," && channels != "Y,") return false;
    image = std::move(layers.front().image);
    return true;
}

}  // namespace

void check_output_path(const std::string& path, const std::string& what) {
    std::error_code ec;
    const fs::path target(path);
    const fs::file_status status = fs::symlink_status(target, ec);
    if (fs::exists(status) && !fs::is_regular_file(fs::status(target, ec)))
        throw OutputError(what + " '" + path +
                          "' exists and is not a regular file: it is never replaced");
    // The directory that will hold it, or its nearest existing ancestor (created on write).
    // Relative paths are walked from "./", so that their last ancestor is the working directory
    // (`out/x.exr` with no `out` yet checks "."); "." / an absolute path is that path.
    fs::path directory = fs::path(".") / target.parent_path();
    while (!fs::exists(directory, ec) && directory.has_parent_path() &&
           directory.parent_path() != directory)
        directory = directory.parent_path();
    const std::string shown = directory.lexically_normal().string();
    if (!fs::is_directory(directory, ec))
        throw OutputError(what + " '" + path + "': '" + shown + "' is not a directory");
    if (::access(directory.c_str(), W_OK | X_OK) != 0)
        throw OutputError(what + " '" + path + "': directory '" + shown + "' is not writable");
}

bool same_file(const std::string& a, const std::string& b) {
    std::error_code ec;
    if (fs::exists(a, ec) && fs::exists(b, ec)) {
        const bool same = fs::equivalent(a, b, ec);
        if (!ec) return same;
    }
    std::error_code error_a, error_b;
    const fs::path canonical_a = fs::weakly_canonical(a, error_a);
    const fs::path canonical_b = fs::weakly_canonical(b, error_b);
    if (!error_a && !error_b) return canonical_a == canonical_b;
    // Unresolvable (e.g. a directory without search permission): compare the spelled paths;
    // two failures must not compare as two equal empty paths.
    return fs::absolute(a, error_a).lexically_normal() ==
           fs::absolute(b, error_b).lexically_normal();
}

void write_text_file(const std::string& path, const std::string& text) {
    OutputFiles files;
    files.add_text(path, text);
    files.commit();
}

OutputFiles::~OutputFiles() {
    for (const Staged& file : staged_) {
        std::error_code ignored;
        fs::remove(file.temporary, ignored);
    }
}

void OutputFiles::add_text(const std::string& path, const std::string& text) {
    const fs::path temporary = temp_path_beside(path);
    staged_.push_back({path, temporary.string()});  // from here on removed on failure
    CheckedFile file(temporary, path);
    file.write(text.data(), text.size());
    file.finish();
}

void OutputFiles::commit() {
    while (!staged_.empty()) {
        const Staged& file = staged_.front();
        std::error_code ec;
        fs::rename(file.temporary, file.path, ec);
        if (ec) throw OutputError("cannot write '" + file.path + "': " + ec.message());
        staged_.erase(staged_.begin());
    }
}

void write_exr(const std::string& path, const std::vector<ExrLayer>& layers,
               const ExrAttributes& attributes) {
    OutputFiles files;
    files.add_exr(path, layers, attributes);
    files.commit();
}

void OutputFiles::add_exr(const std::string& path, const std::vector<ExrLayer>& layers,
                          const ExrAttributes& attributes) {
    if (layers.empty()) throw std::runtime_error("write_exr: no layers for '" + path + "'");
    const int width = layers.front().image.width;
    const int height = layers.front().image.height;
    if (width <= 0 || height <= 0) throw std::runtime_error("write_exr: empty image for " + path);
    for (const ExrLayer& layer : layers) {
        if (layer.image.width != width || layer.image.height != height)
            throw std::runtime_error("write_exr: layer '" + layer.name + "' has a different size");
        if (static_cast<int>(layer.channel_names.size()) != layer.image.channels)
            throw std::runtime_error("write_exr: layer '" + layer.name +
                                     "' channel names do not match its channel count");
    }

    Imf::Header header(width, height);
    header.compression() = Imf::ZIP_COMPRESSION;
    for (const auto& [key, value] : attributes) header.insert(key, Imf::StringAttribute(value));
    Imf::FrameBuffer frame;
    for (const ExrLayer& layer : layers) {
        const std::size_t xstride = sizeof(float) * static_cast<std::size_t>(layer.image.channels);
        const std::size_t ystride = xstride * static_cast<std::size_t>(width);
        for (std::size_t c = 0; c < layer.channel_names.size(); ++c) {
            const std::string name = full_channel_name(layer, c);
            if (header.channels().findChannel(name))
                throw std::runtime_error("write_exr: duplicate channel '" + name + "'");
            header.channels().insert(name, Imf::Channel(Imf::FLOAT));
            // OpenEXR's API takes a non-const base pointer even for writing.
            char* base = reinterpret_cast<char*>(const_cast<float*>(layer.image.pixels.data())) +
                         c * sizeof(float);
            frame.insert(name, Imf::Slice(Imf::FLOAT, base, xstride, ystride));
        }
    }

    const fs::path temporary = temp_path_beside(path);
    staged_.push_back({path, temporary.string()});  // from here on removed on failure
    CheckedFile file(temporary, path);
    try {
        ExrFileStream stream(file, temporary.c_str());
        Imf::OutputFile exr(stream, header);
        exr.setFrameBuffer(frame);
        exr.writePixels(height);
    } catch (const std::exception& e) {
        // A failed write is reported by finish() with the system's reason.
        if (!file.failed()) throw OutputError("cannot write EXR '" + path + "': " + e.what());
    }
    file.finish();
}

std::vector<ExrLayer> read_exr(const std::string& path, ExrAttributes* attributes) {
    try {
        if (const std::string problem = input_file_problem(path); !problem.empty())
            throw InputError(path + ": " + problem);
        Imf::InputFile file(path.c_str());
        const Imf::Header& header = file.header();
        const Imath::Box2i dw = header.dataWindow();
        const int width = dw.max.x - dw.min.x + 1;
        const int height = dw.max.y - dw.min.y + 1;

        // Group channels by the prefix before the last '.'.
        std::map<std::string, std::vector<std::string>> groups;
        for (auto it = header.channels().begin(); it != header.channels().end(); ++it) {
            const std::string full = it.name();
            const std::size_t dot = full.rfind('.');
            if (dot == std::string::npos)
                groups[""].push_back(full);
            else
                groups[full.substr(0, dot)].push_back(full.substr(dot + 1));
        }

        std::vector<ExrLayer> layers;
        layers.reserve(groups.size());
        for (auto& [name, channels] : groups) {
            std::stable_sort(channels.begin(), channels.end(),
                             [](const std::string& a, const std::string& b) {
                                 const int ra = channel_rank(a), rb = channel_rank(b);
                                 return ra != rb ? ra < rb : a < b;
                             });
            ExrLayer layer;
            layer.name = name;
            layer.channel_names = channels;
            layer.image = Image(width, height, static_cast<int>(channels.size()));
            layers.push_back(std::move(layer));
        }

        Imf::FrameBuffer frame;
        for (ExrLayer& layer : layers) {
            const std::size_t xstride =
                sizeof(float) * static_cast<std::size_t>(layer.image.channels);
            const std::size_t ystride = xstride * static_cast<std::size_t>(width);
            // The slice base is addressed with absolute data-window coordinates.
            const std::ptrdiff_t origin =
                -(static_cast<std::ptrdiff_t>(dw.min.x) * static_cast<std::ptrdiff_t>(xstride) +
                  static_cast<std::ptrdiff_t>(dw.min.y) * static_cast<std::ptrdiff_t>(ystride));
            for (std::size_t c = 0; c < layer.channel_names.size(); ++c) {
                char* base = reinterpret_cast<char*>(layer.image.pixels.data()) + origin +
                             static_cast<std::ptrdiff_t>(c * sizeof(float));
                frame.insert(full_channel_name(layer, c),
                             Imf::Slice(Imf::FLOAT, base, xstride, ystride));
            }
        }
        file.setFrameBuffer(frame);
        file.readPixels(dw.min.y, dw.max.y);

        if (attributes) {
            attributes->clear();
            for (auto it = header.begin(); it != header.end(); ++it) {
                if (const auto* s = dynamic_cast<const Imf::StringAttribute*>(&it.attribute()))
                    (*attributes)[it.name()] = s->value();
            }
        }
        return layers;
    } catch (const InputError&) {
        throw;
    } catch (const std::exception& e) {
        throw InputError(path + ": cannot read EXR: " + e.what());
    }
}

float srgb_to_linear(float v) {
    if (v <= 0.04045f) return v / 12.92f;
    return std::pow((v + 0.055f) / 1.055f, 2.4f);
}

float linear_to_srgb(float v) {
    if (v <= 0.0031308f) return 12.92f * v;
    return 1.055f * std::pow(v, 1.f / 2.4f) - 0.055f;
}

void write_png_srgb(const std::string& path, const Image& rgb, float exposure_stops) {
    OutputFiles files;
    files.add_png_srgb(path, rgb, exposure_stops);
    files.commit();
}

void OutputFiles::add_png_srgb(const std::string& path, const Image& rgb, float exposure_stops) {
    if (rgb.width <= 0 || rgb.height <= 0 || rgb.channels < 1)
        throw std::runtime_error("write_png_srgb: empty image for '" + path + "'");
    const int out_channels = rgb.channels >= 3 ? 3 : 1;
    const float scale = std::exp2(exposure_stops);
    std::vector<std::uint8_t> bytes(rgb.pixel_count() * static_cast<std::size_t>(out_channels));
    for (std::size_t p = 0; p < rgb.pixel_count(); ++p) {
        for (int c = 0; c < out_channels; ++c) {
            float v = rgb.pixels[p * static_cast<std::size_t>(rgb.channels) +
                                 static_cast<std::size_t>(c)] *
                      scale;
            if (!std::isfinite(v)) v = 0.f;  // a NaN in a preview is shown black, not propagated
            v = linear_to_srgb(std::clamp(v, 0.f, 1.f));
            bytes[p * static_cast<std::size_t>(out_channels) + static_cast<std::size_t>(c)] =
                static_cast<std::uint8_t>(std::lround(v * 255.f));
        }
    }

    // Encoded in memory (a preview is small), then written with checked calls: libpng does not
    // report every failed write (a full disk left a truncated PNG and exit code 0).
    // libpng's simplified API (1.6): 8-bit sRGB-encoded samples, as the preview's are.
    png_image image{};
    image.version = PNG_IMAGE_VERSION;
    image.width = static_cast<png_uint_32>(rgb.width);
    image.height = static_cast<png_uint_32>(rgb.height);
    image.format = out_channels == 3 ? PNG_FORMAT_RGB : PNG_FORMAT_GRAY;
    png_alloc_size_t size = 0;
    bool ok = png_image_write_to_memory(&image, nullptr, &size, 0, bytes.data(), 0, nullptr) != 0;
    std::vector<unsigned char> encoded(ok ? size : 0);
    ok = ok &&
         png_image_write_to_memory(&image, encoded.data(), &size, 0, bytes.data(), 0, nullptr) != 0;
    if (!ok) {
        const std::string reason = image.message;
        png_image_free(&image);
        throw OutputError("cannot encode PNG '" + path + "': " + reason);
    }
    encoded.resize(size);
    const fs::path temporary = temp_path_beside(path);
    staged_.push_back({path, temporary.string()});  // from here on removed on failure
    CheckedFile file(temporary, path);
    file.write(reinterpret_cast<const char*>(encoded.data()), encoded.size());
    file.finish();
}

Image read_image(const std::string& path) {
    return read_image(path, nullptr);
}

Image read_image(const std::string& path, ImageFileInfo* info) {
    if (const std::string problem = input_file_problem(path); !problem.empty())
        throw InputError(path + ": " + problem);
    if (Image image; read_plain_exr(path, image)) {
        if (info) info->integer_format = false;
        return image;
    }
    const gdmlt_oiio_read_image_fn read = oiio_codec(path);
    Image image;
    const gdmlt_oiio_allocate allocate = [](void* user, int width, int height,
                                            int channels) -> float* {
        if (width <= 0 || height <= 0 || channels <= 0) return nullptr;
        try {
            Image& target = *static_cast<Image*>(user);
            target = Image(width, height, channels);
            return target.pixels.data();
        } catch (const std::bad_alloc&) {
            return nullptr;
        }
    };
    int integer_format = 0;
    char error[512] = {};
    if (read(path.c_str(), allocate, &image, &integer_format, error, sizeof error) != 0)
        throw InputError(path + ": cannot read image: " + error);
    if (info) info->integer_format = integer_format != 0;
    return image;
}

}  // namespace gdmlt
