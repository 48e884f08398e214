// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// SceneDesc: the plain-data result of parsing a Mitsuba XML file (versions 0.6 and 3 spellings).
// No Embree, no meshes loaded, no defaults applied: just objects, their typed properties and
// where in which file each came from, so that later stages can report errors with file and line.
//
// Normalisation done by the parser (so that the builder sees one spelling):
//  - property names are snake_case (0.6 camelCase `toWorld`, `maxDepth` -> `to_world`, `max_depth`)
//    when the scene version is below 2.0;
//  - `$name` substitutions and `<default>` are resolved; `<include>` is inlined;
//  - transforms are composed into one 4x4 matrix (world_from_object), as Mitsuba composes them;
//  - `<ref id=.../>` becomes a child entry pointing at the referenced object (shared, not copied).
#include <cstdint>
#include <limits>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <variant>
#include <vector>

#include "core/math/types.h"

namespace gdmlt {

/// Where something was written: file path as given/resolved, 1-based line and column.
struct FileLoc {
    std::string file;
    int line = 0;
    int column = 0;

    std::string to_string() const;  // "file:line:column"
    bool operator==(const FileLoc&) const = default;
};

/// An error in the user's input (scene file, mesh file, command line). Its message already
/// names the file and line; the CLI prints it and exits with code 2.
class InputError : public std::runtime_error {
  public:
    InputError(const FileLoc& loc, const std::string& what);
    explicit InputError(const std::string& what) : std::runtime_error(what) {}
};

/// Why `path` cannot be read as an input file (scene, include, mesh, texture, EXR), or an empty
/// string when it can: only existing regular files are read ("no such file", "not a regular
/// file": reading a FIFO blocks until a writer appears, and a device such as /dev/zero never
/// ends).
std::string input_file_problem(const std::string& path);

/// An integer property that a 32-bit int must hold (sizes, depths, counts): out of range is an
/// error at `loc`, never a silent truncation (sample_count=2147483648 once rendered 1 spp).
inline int checked_int32(std::int64_t value, const std::string& name, const FileLoc& loc) {
    if (value < std::numeric_limits<int>::min() || value > std::numeric_limits<int>::max())
        throw InputError(
            loc, "'" + name + "' = " + std::to_string(value) + " does not fit a 32-bit integer");
    return static_cast<int>(value);
}

/// `<rgb>` / `<srgb>` value. `srgb` is true when the file gave sRGB-encoded values
/// (0.6 `<srgb>`); the builder linearises.
struct RgbValue {
    Vec3d value = Vec3d::Zero();
    bool srgb = false;
    bool operator==(const RgbValue&) const = default;
};

/// `<point>` or `<vector>`.
struct Vec3Value {
    Vec3d value = Vec3d::Zero();
    bool operator==(const Vec3Value&) const = default;
};

/// `<transform>`: composed matrix, world_from_object (applied to column vectors).
struct TransformValue {
    Mat4d matrix = Mat4d::Identity();
    bool operator==(const TransformValue&) const = default;
};

/// `<spectrum>` kept as text (a single value or "lambda:value, ..." pairs); the builder
/// converts what it supports and rejects the rest with the location.
struct SpectrumValue {
    std::string text;
    bool operator==(const SpectrumValue&) const = default;
};

using PropertyValue = std::variant<bool, std::int64_t, double, std::string, RgbValue, Vec3Value,
                                   TransformValue, SpectrumValue>;

struct Property {
    std::string name;
    PropertyValue value;
    FileLoc loc;
};

/// A child object of another: nested (`<bsdf>` inside `<shape>`) or referenced (`<ref>`).
/// `name` is the `name=` attribute when given (e.g. `<texture name="reflectance">` or
/// `<ref name="bsdf" id="..."/>`), otherwise empty.
struct ChildRef {
    std::string name;
    int object = -1;  // index into SceneDesc::objects
    FileLoc loc;      // where the nesting or the <ref> was written
};

/// One `<tag type="...">` element.
struct ObjectDesc {
    std::string tag;   // "shape", "bsdf", "emitter", "sensor", "film", "sampler", "rfilter",
                       // "integrator", "texture", "medium", ...
    std::string type;  // plugin name: "obj", "diffuse", "area", ...
    std::string id;    // empty when not given
    FileLoc loc;
    std::vector<Property> properties;
    std::vector<ChildRef> children;

    const Property* find(const std::string& name) const {
        for (const Property& p : properties)
            if (p.name == name) return &p;
        return nullptr;
    }
};

struct SceneDesc {
    std::vector<ObjectDesc> objects;  // objects[root] is the <scene> element
    int root = -1;
    std::string version;     // the scene's version attribute, e.g. "3.0.0" or "0.6.0"
    std::string scene_file;  // path of the top-level file
    const ObjectDesc& root_object() const { return objects.at(static_cast<std::size_t>(root)); }
};

struct ParseOptions {
    /// `-D name=value` from the command line; these override `<default>` values.
    std::map<std::string, std::string> defines;
};

/// Parses a Mitsuba XML scene file. Throws InputError (with file:line) on malformed XML,
/// unknown tags, bad attribute values, missing `$name` parameters, missing include files,
/// dangling refs or duplicate ids. Does not validate plugin names or property names: that is
/// the builder's job (it knows which plugins exist).
SceneDesc parse_scene_file(const std::string& path, const ParseOptions& options = {});

/// Same, from a string (used by tests); `virtual_path` is used in messages and to resolve
/// relative include/mesh paths.
SceneDesc parse_scene_string(const std::string& xml, const std::string& virtual_path,
                             const ParseOptions& options = {});

}  // namespace gdmlt
