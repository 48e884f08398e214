// SPDX-License-Identifier: GPL-3.0-or-later
// SceneDesc -> Scene: plugin validation, property reading with unknown-property detection
// (pbrt-v4's ReportUnused, Mitsuba's unqueried-property error), mesh loading, transforms.
#include <filesystem>
#include <iostream>
#include <numbers>
#include <set>

#include "core/geometry/mesh_io.h"
#include "core/image/image_io.h"
#include "core/math/transform.h"
#include "core/scene/plugin_scope.h"
#include "core/scene/scene.h"
#include "core/scene/spectrum_rgb.h"

namespace gdmlt {
namespace {

/// Largest coordinate (and camera near_clip) a scene may have, 100x below the 1.8e18 beyond
/// which Embree rejects a ray (its `ray.valid()` aborts the process): anything near that
/// would overflow single precision in hit-point and offset arithmetic anyway.
constexpr double kMaxWorldCoordinate = 1e16;

/// Throws at `loc` unless every coordinate of `p` is finite and within kMaxWorldCoordinate.
void check_world_point(const Vec3d& p, const FileLoc& loc, const std::string& what) {
    if (!(p.array().abs() <= kMaxWorldCoordinate).all())
        throw InputError(loc, what + " lies outside the traceable world (coordinates must be " +
                                  "finite and within 1e16)");
}

std::string describe(const ObjectDesc& obj) {
    return "<" + obj.tag + " type=\"" + obj.type + "\">";
}

const char* value_kind(const PropertyValue& v) {
    switch (v.index()) {
        case 0:
            return "boolean";
        case 1:
            return "integer";
        case 2:
            return "float";
        case 3:
            return "string";
        case 4:
            return "rgb";
        case 5:
            return "point/vector";
        case 6:
            return "transform";
        case 7:
            return "spectrum";
    }
    return "?";
}

/// Reports problems that --lenient may turn into warnings.
class Diagnostics {
  public:
    explicit Diagnostics(bool lenient) : lenient_(lenient) {}
    void unknown(const FileLoc& loc, const std::string& message) const {
        if (!lenient_) throw InputError(loc, message);
        // One warning per element: an out-of-scope plugin is reported before the build, and
        // its builder then meets it as an unknown one.
        if (!warned_.insert(loc.to_string()).second) return;
        std::cerr << loc.to_string() << ": warning: " << message << " (ignored: --lenient)\n";
    }
    void warn(const FileLoc& loc, const std::string& message) const {
        std::cerr << loc.to_string() << ": warning: " << message << "\n";
    }
    bool lenient() const { return lenient_; }

  private:
    bool lenient_;
    mutable std::set<std::string> warned_;
};

/// Typed access to an object's properties that remembers which were read, so that anything
/// left unread (a misspelt or unsupported property) is reported with its location.
class Properties {
  public:
    Properties(const ObjectDesc& obj, const Diagnostics& diagnostics)
        : obj_(obj), diagnostics_(diagnostics) {}

    bool has(const std::string& name) const { return obj_.find(name) != nullptr; }
    /// The property without marking it read (to dispatch on its type).
    const Property* peek(const std::string& name) const { return obj_.find(name); }

    double get_float(const std::string& name, double fallback) {
        const Property* p = take(name);
        if (!p) return fallback;
        if (const auto* d = std::get_if<double>(&p->value)) return *d;
        if (const auto* i = std::get_if<std::int64_t>(&p->value)) return static_cast<double>(*i);
        throw mismatch(*p, "float");
    }
    std::int64_t get_int(const std::string& name, std::int64_t fallback) {
        const Property* p = take(name);
        if (!p) return fallback;
        if (const auto* i = std::get_if<std::int64_t>(&p->value)) return *i;
        throw mismatch(*p, "integer");
    }
    int get_int32(const std::string& name, int fallback) {
        return checked_int32(get_int(name, fallback), name, loc_of(name));
    }
    bool get_bool(const std::string& name, bool fallback) {
        const Property* p = take(name);
        if (!p) return fallback;
        if (const auto* b = std::get_if<bool>(&p->value)) return *b;
        throw mismatch(*p, "boolean");
    }
    std::string get_string(const std::string& name, const std::string& fallback) {
        const Property* p = take(name);
        if (!p) return fallback;
        if (const auto* s = std::get_if<std::string>(&p->value)) return *s;
        throw mismatch(*p, "string");
    }
    Vec3d get_vec3(const std::string& name, const Vec3d& fallback) {
        const Property* p = take(name);
        if (!p) return fallback;
        if (const auto* v = std::get_if<Vec3Value>(&p->value)) return v->value;
        throw mismatch(*p, "point or vector");
    }
    Transform get_transform(const std::string& name) {
        const Property* p = take(name);
        if (!p) return Transform();
        const auto* t = std::get_if<TransformValue>(&p->value);
        if (!t) throw mismatch(*p, "transform");
        const Transform result(t->matrix);
        if (!result.is_finite()) throw InputError(p->loc, "transform '" + name + "' is singular");
        return result;
    }
    /// An RGB quantity: <rgb>, <srgb> (linearised), <spectrum> (as Mitsuba 3's RGB variants
    /// take it for `use`: core/scene/spectrum_rgb.h) or <float>.
    /// `non_negative`: negative components are an error (reflectances, radiances).
    Rgb get_rgb(const std::string& name, const Rgb& fallback, bool non_negative = true,
                SpectrumUse use = SpectrumUse::Reflectance) {
        const Property* p = take(name);
        if (!p) return fallback;
        Rgb value;
        if (const auto* rgb = std::get_if<RgbValue>(&p->value)) {
            value = rgb->value.cast<float>().array();
            if (rgb->srgb)
                for (int c = 0; c < 3; ++c) value[c] = srgb_to_linear(value[c]);
        } else if (const auto* d = std::get_if<double>(&p->value)) {
            value = Rgb::Constant(static_cast<float>(*d));
        } else if (const auto* i = std::get_if<std::int64_t>(&p->value)) {
            value = Rgb::Constant(static_cast<float>(*i));
        } else if (const auto* s = std::get_if<SpectrumValue>(&p->value)) {
            try {
                value = spectrum_text_to_rgb(s->text, use);
            } catch (const std::invalid_argument& e) {
                throw InputError(p->loc, e.what());
            }
        } else {
            throw mismatch(*p, "rgb, spectrum or float");
        }
        if (!is_finite(value)) throw InputError(p->loc, "'" + name + "' is not finite");
        if (non_negative && (value < 0.f).any())
            throw InputError(p->loc, "'" + name + "' must not be negative");
        return value;
    }
    const FileLoc& loc_of(const std::string& name) const {
        const Property* p = obj_.find(name);
        return p ? p->loc : obj_.loc;
    }

    /// Reports every property that no reader asked for.
    void check_all_used() const {
        for (const Property& p : obj_.properties)
            if (!used_.count(p.name))
                diagnostics_.unknown(p.loc, "unknown property '" + p.name + "' (" +
                                                value_kind(p.value) + ") in " + describe(obj_));
    }
    /// Marks properties as read on purpose though without effect (e.g. film pixel formats).
    void ignore(const std::string& name) {
        if (has(name)) used_.insert(name);
    }

  private:
    const Property* take(const std::string& name) {
        const Property* p = obj_.find(name);
        if (p) used_.insert(name);
        return p;
    }
    InputError mismatch(const Property& p, const std::string& expected) const {
        return InputError(p.loc, "property '" + p.name + "' of " + describe(obj_) + " should be " +
                                     expected + ", found " + value_kind(p.value));
    }
    const ObjectDesc& obj_;
    const Diagnostics& diagnostics_;
    std::set<std::string> used_;
};

TriangleMesh make_rectangle() {
    TriangleMesh m;
    m.positions = {{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}};
    m.uvs = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
    m.indices = {0, 1, 2, 2, 3, 0};
    return m;
}

TriangleMesh make_cube() {
    TriangleMesh m;
    // Six faces of [-1,1]^3, four vertices each so that every face is flat.
    const Vec3f axes[3] = {Vec3f::UnitX(), Vec3f::UnitY(), Vec3f::UnitZ()};
    for (int axis = 0; axis < 3; ++axis) {
        for (float side : {-1.f, 1.f}) {
            const Vec3f n = side * axes[axis];
            const Vec3f a = axes[(axis + 1) % 3], b = axes[(axis + 2) % 3];
            // Order the corners counter-clockwise as seen from outside (cross(a, b) = axis).
            const Vec3f s = side > 0.f ? a : b, t = side > 0.f ? b : a;
            const auto base = static_cast<std::uint32_t>(m.positions.size());
            m.positions.push_back(n - s - t);
            m.positions.push_back(n + s - t);
            m.positions.push_back(n + s + t);
            m.positions.push_back(n - s + t);
            m.uvs.insert(m.uvs.end(), {{0, 0}, {1, 0}, {1, 1}, {0, 1}});
            m.indices.insert(m.indices.end(), {base, base + 1, base + 2, base + 2, base + 3, base});
        }
    }
    return m;
}

/// The unit disk in z = 0 as a fine triangle fan: the area differs from pi by 1e-4 relative
/// at 256 segments (regular polygon area = pi * sinc(2 pi / n)).
TriangleMesh make_disk() {
    constexpr int kSegments = 256;
    TriangleMesh m;
    m.positions.push_back(Vec3f::Zero());
    m.uvs.push_back({0.5f, 0.5f});
    for (int i = 0; i < kSegments; ++i) {
        const float phi = 2.f * kPi * static_cast<float>(i) / kSegments;
        m.positions.emplace_back(std::cos(phi), std::sin(phi), 0.f);
        m.uvs.emplace_back(0.5f + 0.5f * std::cos(phi), 0.5f + 0.5f * std::sin(phi));
    }
    for (std::uint32_t i = 0; i < kSegments; ++i)
        m.indices.insert(m.indices.end(), {0u, 1 + i, 1 + (i + 1) % kSegments});
    return m;
}

void transform_mesh(TriangleMesh& mesh, const Transform& world_from_object) {
    for (Vec3f& p : mesh.positions) p = world_from_object.apply_point(p);
    for (Vec3f& n : mesh.normals) n = world_from_object.apply_normal(n);
    // A mirroring transform reverses the winding; swap two corners so that the geometric normal
    // (from the winding) keeps agreeing with the transformed vertex normals.
    if (world_from_object.flips_handedness()) {
        for (std::size_t t = 0; t + 2 < mesh.indices.size(); t += 3)
            std::swap(mesh.indices[t + 1], mesh.indices[t + 2]);
        // Vertex attributes are stored per corner: their corners 1 and 2 swap likewise.
        for (auto& attribute : mesh.attributes) {
            if (attribute->per_face) continue;
            MeshAttribute swapped = *attribute;
            const auto dim = static_cast<std::size_t>(swapped.dim);
            for (std::size_t t = 0; t + 3 * dim <= swapped.values.size(); t += 3 * dim)
                std::swap_ranges(swapped.values.begin() + static_cast<std::ptrdiff_t>(t + dim),
                                 swapped.values.begin() + static_cast<std::ptrdiff_t>(t + 2 * dim),
                                 swapped.values.begin() + static_cast<std::ptrdiff_t>(t + 2 * dim));
            attribute = std::make_shared<const MeshAttribute>(std::move(swapped));
        }
    }
}

struct Builder {
    const SceneDesc& desc;
    Diagnostics diagnostics;

    std::vector<Shape> shapes;
    std::vector<Bsdf> bsdfs;
    std::vector<Emitter> emitters;
    std::map<int, int> bsdf_of_object;   // SceneDesc object index -> bsdfs index
    std::vector<std::string> bsdf_kind;  // per bsdfs entry, for SceneFeatures
    Camera camera;
    bool has_camera = false;
    IntegratorSettings integrator;
    SamplerSettings sampler;
    SceneFeatures features;
    std::map<std::string, std::size_t> counts;
    /// Shapegroup meshes by object index, built once and shared by the instances that place them.
    struct GroupMesh {
        std::shared_ptr<const Shape> shape;
        Eigen::AlignedBox3d box;  // of its vertices, in the group's space
    };
    std::map<int, GroupMesh> group_meshes;
    /// Loaded images by (file, raw), shared by every texture that names them.
    std::map<std::pair<std::string, bool>, std::shared_ptr<const BitmapData>> bitmaps;
    /// The mesh_attribute textures, bound to the shapes once they are built.
    struct MeshAttributeUse {
        std::string name;
        FileLoc loc;
        std::shared_ptr<MeshAttributeBinding> binding;
    };
    std::vector<MeshAttributeUse> mesh_attribute_textures;

    const ObjectDesc& object(int index) const {
        return desc.objects.at(static_cast<std::size_t>(index));
    }

    /// Texture-capable parameters of one object: a property (constant) or a nested / referenced
    /// `<texture name="...">` child. Remembers which children were consumed so that anything
    /// else nested in the object is reported.
    class TextureParams {
      public:
        TextureParams(Builder& builder, const ObjectDesc& obj, Properties& props)
            : builder_(builder), obj_(obj), props_(props) {}

        RgbTexture rgb(const std::string& name, const Rgb& fallback,
                       SpectrumUse use = SpectrumUse::Reflectance) {
            if (const ChildRef* child = find(name)) {
                if (props_.has(name))
                    throw InputError(child->loc,
                                     "'" + name + "' given both as a property and as a texture");
                return builder_.build_texture(builder_.object(child->object));
            }
            return RgbTexture(props_.get_rgb(name, fallback, true, use));
        }
        FloatTexture scalar(const std::string& name, float fallback) {
            if (const ChildRef* child = find(name)) {
                if (props_.has(name))
                    throw InputError(child->loc,
                                     "'" + name + "' given both as a property and as a texture");
                return FloatTexture(builder_.build_texture(builder_.object(child->object)));
            }
            return FloatTexture(static_cast<float>(props_.get_float(name, fallback)));
        }
        bool has(const std::string& name) {
            return props_.has(name) || find_unmarked(name) != nullptr;
        }
        /// The nested `<bsdf>` children (a mask's or blend's components), in file order.
        std::vector<const ChildRef*> nested_bsdfs() {
            std::vector<const ChildRef*> out;
            for (std::size_t i = 0; i < obj_.children.size(); ++i)
                if (builder_.object(obj_.children[i].object).tag == "bsdf") {
                    used_.insert(i);
                    out.push_back(&obj_.children[i]);
                }
            return out;
        }
        /// The nested `<texture>` children whatever their names, in file order (a bump map's
        /// height).
        std::vector<const ChildRef*> nested_textures() {
            std::vector<const ChildRef*> out;
            for (std::size_t i = 0; i < obj_.children.size(); ++i)
                if (builder_.object(obj_.children[i].object).tag == "texture") {
                    used_.insert(i);
                    out.push_back(&obj_.children[i]);
                }
            return out;
        }
        /// Reports nested elements that no parameter asked for.
        void check_all_used() const {
            for (std::size_t i = 0; i < obj_.children.size(); ++i)
                if (!used_.count(i)) {
                    const ObjectDesc& c = builder_.object(obj_.children[i].object);
                    builder_.diagnostics.unknown(
                        obj_.children[i].loc, "unexpected nested element " + describe(c) +
                                                  (obj_.children[i].name.empty()
                                                       ? ""
                                                       : " named '" + obj_.children[i].name + "'") +
                                                  " in " + describe(obj_));
                }
        }

      private:
        const ChildRef* find_unmarked(const std::string& name) const {
            for (const ChildRef& c : obj_.children)
                if (c.name == name && builder_.object(c.object).tag == "texture") return &c;
            return nullptr;
        }
        const ChildRef* find(const std::string& name) {
            for (std::size_t i = 0; i < obj_.children.size(); ++i) {
                const ChildRef& c = obj_.children[i];
                if (c.name == name && builder_.object(c.object).tag == "texture") {
                    used_.insert(i);
                    return &c;
                }
            }
            return nullptr;
        }

        Builder& builder_;
        const ObjectDesc& obj_;
        Properties& props_;
        std::set<std::size_t> used_;
    };

    static UvTransform read_uv_transform(Properties& props) {
        const Transform t = props.get_transform("to_uv");
        UvTransform uv;
        uv.linear = t.matrix.topLeftCorner<2, 2>().cast<float>();
        uv.offset = t.matrix.block<2, 1>(0, 3).cast<float>();
        return uv;
    }

    RgbTexture build_texture(const ObjectDesc& obj) {
        Properties props(obj, diagnostics);
        features.has_textures = true;
        if (!obj.children.empty())
            diagnostics.unknown(object(obj.children.front().object).loc,
                                "unexpected nested element in " + describe(obj));
        if (obj.type == "bitmap") {
            const std::string filename = props.get_string("filename", "");
            if (filename.empty()) throw InputError(obj.loc, describe(obj) + " needs a 'filename'");
            const bool raw = props.get_bool("raw", false);
            BitmapTexture b;
            const std::string filter = props.get_string("filter_type", "bilinear");
            if (filter == "bilinear")
                b.filter = FilterMode::Bilinear;
            else if (filter == "nearest")
                b.filter = FilterMode::Nearest;
            else
                throw InputError(props.loc_of("filter_type"),
                                 "filter_type must be bilinear or nearest");
            const std::string wrap = props.get_string("wrap_mode", "repeat");
            if (wrap == "repeat")
                b.wrap = WrapMode::Repeat;
            else if (wrap == "mirror")
                b.wrap = WrapMode::Mirror;
            else if (wrap == "clamp")
                b.wrap = WrapMode::Clamp;
            else
                throw InputError(props.loc_of("wrap_mode"),
                                 "wrap_mode must be repeat, mirror or clamp");
            b.to_uv = read_uv_transform(props);
            // Mitsuba 3's storage precision ("variant", "fp16", "fp32"): texels are kept as
            // float here whatever it says.
            const std::string format = props.get_string("format", "variant");
            if (format != "variant" && format != "fp16" && format != "fp32")
                throw InputError(props.loc_of("format"), "format must be variant, fp16 or fp32");
            props.check_all_used();
            auto& cached = bitmaps[{filename, raw}];
            if (!cached) {
                try {
                    cached = std::make_shared<const BitmapData>(load_bitmap(filename, raw));
                } catch (const InputError& e) {
                    throw InputError(props.loc_of("filename"), e.what());
                }
            }
            b.data = cached;
            return RgbTexture(TextureModel(b));
        }
        if (obj.type == "checkerboard") {
            CheckerboardTexture c;
            c.color0 = props.get_rgb("color0", Rgb::Constant(0.4f));
            c.color1 = props.get_rgb("color1", Rgb::Constant(0.2f));
            c.to_uv = read_uv_transform(props);
            props.check_all_used();
            return RgbTexture(TextureModel(c));
        }
        if (obj.type == "rawconstant") {
            // Mitsuba 3's rawconstant: a float or a 3-vector, no colour conversion.
            Rgb value = Rgb::Constant(1.f);
            if (const Property* p = props.peek("value");
                p && std::holds_alternative<Vec3Value>(p->value))
                value = props.get_vec3("value", Vec3d::Ones()).cast<float>().array();
            else
                value = Rgb::Constant(static_cast<float>(props.get_float("value", 1.0)));
            props.check_all_used();
            if (!is_finite(value)) throw InputError(obj.loc, "rawconstant: value must be finite");
            return RgbTexture(value);
        }
        if (obj.type == "mesh_attribute") {
            // Mitsuba 3's mesh_attribute: a PLY mesh's vertex_* or face_* values; bound to the
            // shapes that have them once all shapes are built (bind_mesh_attributes).
            MeshAttributeTexture m;
            m.name = props.get_string("name", "");
            if (m.name.rfind("vertex_", 0) != 0 && m.name.rfind("face_", 0) != 0)
                throw InputError(
                    props.loc_of("name"),
                    "mesh_attribute: name must start with vertex_ or face_ (got '" + m.name + "')");
            m.scale = static_cast<float>(props.get_float("scale", 1.0));
            if (!std::isfinite(m.scale))
                throw InputError(props.loc_of("scale"), "mesh_attribute: scale must be finite");
            props.check_all_used();
            m.binding = std::make_shared<MeshAttributeBinding>();
            mesh_attribute_textures.push_back({m.name, obj.loc, m.binding});
            return RgbTexture(TextureModel(m));
        }
        diagnostics.unknown(obj.loc, "unknown texture '" + obj.type +
                                         "' (supported: bitmap, checkerboard, rawconstant, "
                                         "mesh_attribute)");
        return RgbTexture(Rgb::Constant(0.5f));
    }

    /// A plugin outside gdmlt's scope anywhere in the file says so before anything is built
    /// (with --lenient: a warning, and the element is then skipped as an unknown one is).
    void check_scope() const {
        for (const ObjectDesc& obj : desc.objects)
            if (const auto reason = out_of_scope_reason(obj.tag, obj.type))
                diagnostics.unknown(obj.loc, out_of_scope_message(obj.tag, obj.type, *reason));
    }

    /// Gives every mesh_attribute texture the attribute of its name on each shape that has
    /// one; a name no mesh of the scene has is an error at the texture (Mitsuba 3 fails at
    /// render time on such a shape).
    void bind_mesh_attributes() {
        for (const MeshAttributeUse& use : mesh_attribute_textures) {
            use.binding->by_shape.assign(shapes.size(), nullptr);
            bool found = false;
            for (std::size_t i = 0; i < shapes.size(); ++i) {
                // An instance's attributes are its shared mesh's (the same corners).
                const TriangleMesh* mesh = shapes[i].object_mesh();
                if (!mesh) continue;
                use.binding->by_shape[i] = mesh->attribute(use.name);
                found = found || use.binding->by_shape[i] != nullptr;
            }
            if (!found)
                throw InputError(
                    use.loc, "mesh_attribute: no mesh of the scene has an attribute '" + use.name +
                                 "' (PLY vertex or face properties)");
        }
    }

    void build_root() {
        check_scope();
        const ObjectDesc& root = desc.root_object();
        for (const ChildRef& child : root.children) {
            const ObjectDesc& obj = object(child.object);
            if (obj.tag == "shape" && obj.type == "shapegroup") {
                // Declared for the instances that refer to it; built as theirs.
            } else if (obj.tag == "shape" && obj.type == "instance") {
                build_instance(obj);
            } else if (obj.tag == "shape") {
                build_shape(obj);
            } else if (obj.tag == "bsdf") {
                bsdf_index(child.object);  // declared for later refs; built once
            } else if (obj.tag == "emitter") {
                // An area emitter declared at the top for the shapes that <ref> it (Mitsuba's
                // cbox-rgb.xml) is built as theirs; as in Mitsuba 3, not on its own.
                if (!(obj.type == "area" && referenced_by_a_shape(child.object)))
                    build_emitter(obj, -1);
            } else if (obj.tag == "sensor") {
                if (has_camera) throw InputError(obj.loc, "only one <sensor> is supported");
                build_sensor(obj);
            } else if (obj.tag == "integrator") {
                build_integrator(obj);
            } else if (obj.tag == "sampler" && referenced_by_any(child.object)) {
                // Declared for the sensor that refers to it (Mitsuba's sampler_*.xml scenes);
                // built there.
            } else if (obj.tag == "texture") {
                // A declaration for later <ref>s; built where it is used. Validate it now so
                // that errors in unused textures are still reported.
                build_texture(obj);
            } else {
                diagnostics.unknown(obj.loc,
                                    "unsupported element " + describe(obj) + " in <scene>");
            }
        }
        if (!has_camera) {
            // Mitsuba adds a default perspective sensor; so do we, with its film defaults.
            Film film;
            film.crop_width = film.width;
            film.crop_height = film.height;
            film.filter = PixelFilter::gaussian(0.5f);  // Mitsuba's default film's filter
            camera = Camera(Transform(), film, 45.f, "x", 0.01f);
        }
    }

    void build_integrator(const ObjectDesc& obj) {
        if (obj.type == "moment") {
            // Mitsuba 3's `moment` (40 of the scenes in its data repository): the image is its
            // first nested integrator's, and the path tracer writes the samples' first and
            // second moments in XYZ as layers `<name>` and `m2_<name>` (cli/main.cpp).
            const ObjectDesc* nested = nullptr;
            std::string name;
            int unnamed = 0;
            for (const ChildRef& child : obj.children) {
                const ObjectDesc& c = object(child.object);
                if (c.tag != "integrator") {
                    diagnostics.unknown(c.loc, "unsupported element " + describe(c) +
                                                   " in <integrator type=\"moment\">");
                } else if (!nested) {
                    nested = &c;
                    // Mitsuba names an unnamed child `_arg_<n>`, n counting unnamed children.
                    name = child.name.empty() ? "_arg_" + std::to_string(unnamed) : child.name;
                }
                if (c.tag == "integrator" && child.name.empty()) ++unnamed;
            }
            if (!nested)
                throw InputError(obj.loc,
                                 "<integrator type=\"moment\"> needs a nested <integrator>");
            Properties(obj, diagnostics).check_all_used();
            build_integrator(*nested);
            integrator.moment = name;
            return;
        }
        if (obj.type == "aov") {
            // Mitsuba 3's `aov`: the image of its nested integrator, and the first hit's
            // variables as layers (core/scene/aov.h). Mitsuba also writes further nested
            // integrators' images as layers; one is supported here.
            Properties props(obj, diagnostics);
            const std::string list = props.get_string("aovs", "");
            std::vector<AovRequest> aovs;
            std::size_t start = 0;
            while (start <= list.size()) {
                std::size_t end = list.find(',', start);
                if (end == std::string::npos) end = list.size();
                std::string item = list.substr(start, end - start);
                item.erase(0, item.find_first_not_of(" \t\n"));
                item.erase(item.find_last_not_of(" \t\n") + 1);
                start = end + 1;
                if (item.empty()) continue;
                const std::size_t colon = item.find(':');
                const std::optional<AovType> type = colon == std::string::npos
                                                        ? std::nullopt
                                                        : parse_aov_type(item.substr(colon + 1));
                if (colon == 0 || !type)
                    throw InputError(
                        props.loc_of("aovs"),
                        "aovs: '" + item + "' is not name:type with a type among " + kAovTypeNames);
                aovs.push_back(AovRequest{item.substr(0, colon), *type});
            }
            if (aovs.empty())
                throw InputError(obj.loc, "<integrator type=\"aov\"> needs a list of aovs");
            props.check_all_used();
            const ObjectDesc* nested = nullptr;
            for (const ChildRef& child : obj.children) {
                const ObjectDesc& c = object(child.object);
                if (c.tag != "integrator" || nested)
                    diagnostics.unknown(c.loc, "unsupported element " + describe(c) +
                                                   " in <integrator type=\"aov\"> (one nested "
                                                   "integrator is rendered)");
                else
                    nested = &c;
            }
            // Without a nested integrator Mitsuba writes only the AOVs; the path tracer's image
            // is written here as the beauty.
            if (nested) build_integrator(*nested);
            integrator.aovs = std::move(aovs);
            return;
        }
        if (obj.type == "direct") {
            // Mitsuba 3's `direct`: the light seen directly and direct illumination at the first
            // hit, by MIS of emitter and BSDF samples: the path tracer's expectation with
            // max_depth 2. Its emitter_samples / bsdf_samples (shading_samples sets both) only
            // change how many samples of each technique a camera ray takes, i.e. the noise.
            Properties props(obj, diagnostics);
            for (const char* name : {"emitter_samples", "bsdf_samples", "shading_samples"})
                if (props.has(name) && props.get_int32(name, 1) < 0)
                    throw InputError(props.loc_of(name), std::string(name) + " must be >= 0");
            integrator.desc = obj;
            integrator.type = "path";
            integrator.max_depth = 2;
            integrator.rr_depth = 5;
            integrator.hide_emitters = props.get_bool("hide_emitters", false);
            props.check_all_used();
            return;
        }
        static const std::set<std::string> known = {"path", "ptracer", "bdpt", "pssmlt",
                                                    "mmlt", "gdpt",    "gdmlt"};
        integrator.desc = obj;
        integrator.type = obj.type;
        if (!known.count(obj.type)) {
            diagnostics.unknown(
                obj.loc, "unknown integrator '" + obj.type +
                             "' (supported: path, ptracer, bdpt, pssmlt, mmlt, gdpt, gdmlt)");
            integrator.type = "path";
        }
        Properties props(obj, diagnostics);
        integrator.max_depth = props.get_int32("max_depth", -1);
        integrator.rr_depth = props.get_int32("rr_depth", 5);
        integrator.hide_emitters = props.get_bool("hide_emitters", false);
        if (integrator.max_depth < -1 || integrator.max_depth == 0)
            throw InputError(props.loc_of("max_depth"), "max_depth must be -1 or at least 1");
        if (integrator.rr_depth < 1)
            throw InputError(props.loc_of("rr_depth"), "rr_depth must be at least 1");
        // The other integrators validate their own properties; the path tracer knows all of its.
        // Mitsuba 3's ptracer also has samples_per_pass, which only splits its work.
        if (obj.type == "ptracer") props.get_int32("samples_per_pass", -1);
        if (obj.type == "path" || obj.type == "ptracer" || obj.type == "bdpt")
            props.check_all_used();
    }

    /// Mitsuba 3's parse_fov, shared by the perspective sensor and the projector: `fov` (degrees)
    /// along `fov_axis`, or else `focal_length` ("50mm" when neither is given) of a 36 x 24 mm
    /// full-frame film along its diagonal.
    std::pair<float, std::string> read_fov(Properties& props) const {
        if (props.has("fov") && props.has("focal_length"))
            throw InputError(props.loc_of("focal_length"),
                             "give either fov or focal_length, not both");
        float fov = 0.f;
        std::string fov_axis = "diagonal";
        if (props.has("fov")) {
            fov = static_cast<float>(props.get_float("fov", 39.3077));
            fov_axis = props.get_string("fov_axis", "x");
        } else {
            std::string focal = props.get_string("focal_length", "50mm");
            const FileLoc& focal_loc = props.loc_of("focal_length");
            if (focal.size() > 2 && focal.compare(focal.size() - 2, 2, "mm") == 0)
                focal.resize(focal.size() - 2);
            double millimetres = 0.0;
            try {
                std::size_t used = 0;
                millimetres = std::stod(focal, &used);
                if (used != focal.size()) millimetres = 0.0;
            } catch (const std::exception&) {
                millimetres = 0.0;
            }
            if (!(millimetres > 0.0 && std::isfinite(millimetres)))
                throw InputError(focal_loc, "focal_length must be of the form <x>mm, x > 0");
            fov = static_cast<float>(
                2.0 * std::atan(std::sqrt(36.0 * 36.0 + 24.0 * 24.0) / (2.0 * millimetres)) *
                180.0 / std::numbers::pi);
            props.ignore("fov_axis");  // Mitsuba does not read it with a focal length
        }
        if (!(fov > 0.f && fov < 180.f))
            throw InputError(props.loc_of("fov"), "fov must be in (0, 180)");
        static const std::set<std::string> axes = {"x", "y", "diagonal", "smaller", "larger"};
        if (!axes.count(fov_axis))
            throw InputError(props.loc_of("fov_axis"),
                             "fov_axis must be x, y, diagonal, smaller or larger");
        return {fov, fov_axis};
    }

    void build_sensor(const ObjectDesc& obj) {
        const bool orthographic = obj.type == "orthographic";
        const bool thin_lens = obj.type == "thinlens";
        if (obj.type != "perspective" && !orthographic && !thin_lens)
            throw InputError(obj.loc, "unsupported sensor '" + obj.type +
                                          "' (supported: perspective, thinlens, orthographic)");
        Properties props(obj, diagnostics);
        std::pair<float, std::string> fov{90.f, "x"};
        if (!orthographic) fov = read_fov(props);
        const auto near_clip = static_cast<float>(props.get_float("near_clip", 0.01));
        // Camera rays end at far_clip (Mitsuba's default 1e4).
        const double far_clip = props.get_float("far_clip", 1e4);
        // Mitsuba 3's projective cameras all read focus_distance (default far_clip); only the
        // thin lens uses it, so a pinhole camera given one (Mitsuba's own cbox.xml) renders as
        // without it.
        float focus_distance = 0.f, aperture_radius = 0.f;
        if (thin_lens) {
            focus_distance = static_cast<float>(props.get_float("focus_distance", far_clip));
            aperture_radius = static_cast<float>(props.get_float("aperture_radius", 0.0));
            if (!props.has("aperture_radius"))
                throw InputError(obj.loc, "thinlens needs aperture_radius");
            if (!(focus_distance > 0.f && focus_distance <= kMaxWorldCoordinate))
                throw InputError(props.loc_of("focus_distance"),
                                 "focus_distance must be positive and finite");
            if (!(aperture_radius >= 0.f && aperture_radius <= kMaxWorldCoordinate))
                throw InputError(props.loc_of("aperture_radius"),
                                 "aperture_radius must be zero or positive and finite");
        } else {
            props.ignore("focus_distance");
        }
        const Transform world_from_camera = props.get_transform("to_world");
        check_world_point(world_from_camera.apply_point(Vec3d(Vec3d::Zero())),
                          props.loc_of("to_world"), "the camera");
        if (thin_lens) {
            // Mitsuba 3 refuses a scaling to_world for the thin lens: its lens radius and
            // focus distance are world lengths.
            const Eigen::Matrix3d linear = world_from_camera.matrix.topLeftCorner<3, 3>();
            if (!(linear.transpose() * linear).isIdentity(1e-3))
                throw InputError(props.loc_of("to_world"),
                                 "a thinlens sensor's to_world must not scale (as in Mitsuba 3)");
        }
        if (!(near_clip > 0.f && near_clip <= kMaxWorldCoordinate))
            throw InputError(props.loc_of("near_clip"),
                             "near_clip must be positive and finite (at most 1e16)");
        if (!(far_clip > near_clip))
            throw InputError(props.loc_of("far_clip"), "far_clip must exceed near_clip");
        props.check_all_used();

        Film film;  // Mitsuba's default film: 768 x 576, Gaussian filter
        film.crop_width = film.width;
        film.crop_height = film.height;
        film.filter = PixelFilter::gaussian(0.5f);
        bool has_film = false;
        for (const ChildRef& child : obj.children) {
            const ObjectDesc& c = object(child.object);
            if (c.tag == "film") {
                film = build_film(c);
                has_film = true;
            } else if (c.tag == "sampler") {
                build_sampler(c);
            } else {
                diagnostics.unknown(c.loc, "unsupported element " + describe(c) + " in <sensor>");
            }
        }
        (void)has_film;
        if (orthographic)
            camera = Camera::orthographic(world_from_camera, film, near_clip);
        else if (thin_lens)
            camera = Camera::thin_lens(world_from_camera, film, fov.first, fov.second, near_clip,
                                       aperture_radius, focus_distance);
        else
            camera = Camera(world_from_camera, film, fov.first, fov.second, near_clip);
        camera.set_far_clip(static_cast<float>(std::min<double>(far_clip, kInfinity)));
        has_camera = true;
    }

    PixelFilter build_filter(const ObjectDesc& obj) {
        Properties props(obj, diagnostics);
        PixelFilter filter;
        if (obj.type == "box") {
            // Mitsuba's box has no parameters (radius 1/2).
        } else if (obj.type == "tent") {
            const double radius = props.get_float("radius", 1.0);
            if (!(radius > 0.0 && radius <= 16.0))
                throw InputError(props.loc_of("radius"), "the tent's radius must be in (0, 16]");
            filter = PixelFilter::tent(static_cast<float>(radius));
        } else if (obj.type == "gaussian") {
            const double stddev = props.get_float("stddev", 0.5);
            if (!(stddev > 0.0 && stddev <= 4.0))
                throw InputError(props.loc_of("stddev"), "the gaussian's stddev must be in (0, 4]");
            filter = PixelFilter::gaussian(static_cast<float>(stddev));
        } else {
            diagnostics.unknown(obj.loc, "unsupported reconstruction filter '" + obj.type +
                                             "' (supported: box, tent, gaussian)");
        }
        props.check_all_used();
        return filter;
    }

    Film build_film(const ObjectDesc& obj) {
        if (obj.type != "hdrfilm")
            diagnostics.unknown(obj.loc,
                                "unsupported film '" + obj.type + "' (supported: hdrfilm)");
        Properties props(obj, diagnostics);
        Film film;
        film.width = props.get_int32("width", 768);
        film.height = props.get_int32("height", 576);
        if (film.width < 1 || film.height < 1 || film.width > 1 << 16 || film.height > 1 << 16)
            throw InputError(obj.loc, "film size must be between 1 and 65536 pixels");
        film.crop_offset_x = props.get_int32("crop_offset_x", 0);
        film.crop_offset_y = props.get_int32("crop_offset_y", 0);
        // Checked before the default crop size subtracts them (no int overflow).
        if (film.crop_offset_x < 0 || film.crop_offset_y < 0 || film.crop_offset_x >= film.width ||
            film.crop_offset_y >= film.height)
            throw InputError(obj.loc, "crop window lies outside the film");
        film.crop_width = props.get_int32("crop_width", film.width - film.crop_offset_x);
        film.crop_height = props.get_int32("crop_height", film.height - film.crop_offset_y);
        if (film.crop_offset_x < 0 || film.crop_offset_y < 0 || film.crop_width < 1 ||
            film.crop_height < 1 ||
            std::int64_t{film.crop_offset_x} + film.crop_width > film.width ||
            std::int64_t{film.crop_offset_y} + film.crop_height > film.height)
            throw InputError(obj.loc, "crop window lies outside the film");
        // Output formats are ours to choose (float32 RGB EXR); accept Mitsuba's spellings.
        for (const char* name : {"pixel_format", "component_format", "file_format", "banner",
                                 "high_quality_edges", "rfilter"})
            props.ignore(name);
        props.check_all_used();
        bool has_filter = false;
        for (const ChildRef& child : obj.children) {
            const ObjectDesc& c = object(child.object);
            if (c.tag == "rfilter") {
                if (has_filter) throw InputError(c.loc, "a film takes one <rfilter>");
                has_filter = true;
                film.filter = build_filter(c);
            } else {
                diagnostics.unknown(c.loc, "unsupported element " + describe(c) + " in <film>");
            }
        }
        // Mitsuba 3's default: a Gaussian of standard deviation 0.5 pixels.
        if (!has_filter) film.filter = PixelFilter::gaussian(0.5f);
        return film;
    }

    void build_sampler(const ObjectDesc& obj) {
        // Mitsuba's other samplers place the same number of samples differently (strata,
        // low-discrepancy sequences): the image they converge to is the independent sampler's,
        // which every integrator here uses (its streams are what makes renders reproducible
        // at any thread count and what the Markov chains mutate).
        static const std::set<std::string> kinds = {"independent", "stratified", "multijitter",
                                                    "orthogonal", "ldsampler"};
        if (!kinds.count(obj.type))
            diagnostics.unknown(obj.loc, "unsupported sampler '" + obj.type +
                                             "' (supported: independent, and stratified, "
                                             "multijitter, orthogonal, ldsampler as independent)");
        Properties props(obj, diagnostics);
        for (const char* name : {"jitter", "strength", "dimension"}) props.ignore(name);
        const int spp = props.get_int32("sample_count", 4);
        const std::int64_t seed = props.get_int("seed", 0);
        if (spp < 1)
            throw InputError(props.loc_of("sample_count"), "sample_count must be positive");
        props.check_all_used();
        sampler.sample_count = spp;
        sampler.seed = static_cast<std::uint64_t>(seed);
    }

    /// An index of refraction given as a number or as one of Mitsuba's names ("bk7", "air").
    float read_ior(Properties& props, const std::string& name, float fallback) {
        const Property* p = props.peek(name);
        if (!p) return fallback;
        if (std::holds_alternative<std::string>(p->value)) {
            const std::string text = props.get_string(name, "");
            if (auto ior = lookup_ior(text)) return *ior;
            throw InputError(p->loc, "unknown named index of refraction '" + text + "'");
        }
        const auto v = static_cast<float>(props.get_float(name, fallback));
        if (!(v > 0.f) || !std::isfinite(v))
            throw InputError(p->loc, "'" + name + "' must be positive");
        return v;
    }

    /// Complex IOR of a conductor: eta/k given, a named material, or "none" (perfect mirror).
    void read_conductor_ior(Properties& props, Rgb* eta, Rgb* k, bool* perfect_mirror) {
        const std::string material = props.get_string("material", "none");
        *perfect_mirror = true;
        if (props.has("eta") || props.has("k")) {
            *eta = props.get_rgb("eta", Rgb::Zero(), true, SpectrumUse::Unbounded);
            *k = props.get_rgb("k", Rgb::Ones(), true, SpectrumUse::Unbounded);
            *perfect_mirror = false;
        } else if (material != "none") {
            const auto ior = lookup_conductor(material);
            if (!ior)
                throw InputError(props.loc_of("material"),
                                 "unknown conductor material '" + material +
                                     "' (known: none and Mitsuba 3's list: " + conductor_names() +
                                     ")");
            *eta = ior->eta;
            *k = ior->k;
            *perfect_mirror = false;
        }
    }

    static MicrofacetType read_distribution(Properties& props) {
        const std::string name = props.get_string("distribution", "beckmann");
        if (name == "beckmann") return MicrofacetType::Beckmann;
        if (name == "ggx") return MicrofacetType::Ggx;
        throw InputError(props.loc_of("distribution"),
                         "distribution must be beckmann or ggx (got '" + name + "')");
    }

    /// Mitsuba's microfacet parameters: distribution, alpha or (alpha_u and alpha_v), and
    /// sample_visible. Alphas may be textures.
    MicrofacetRoughness read_roughness(Properties& props, TextureParams& textures,
                                       const ObjectDesc& obj) {
        MicrofacetRoughness r;
        r.type = read_distribution(props);
        r.sample_visible = props.get_bool("sample_visible", true);
        const bool anisotropic = textures.has("alpha_u") || textures.has("alpha_v");
        if (anisotropic) {
            if (textures.has("alpha"))
                throw InputError(obj.loc, "give either alpha or alpha_u/alpha_v, not both");
            if (!textures.has("alpha_u") || !textures.has("alpha_v"))
                throw InputError(obj.loc, "alpha_u and alpha_v must be given together");
            r.alpha_u = textures.scalar("alpha_u", 0.1f);
            r.alpha_v = textures.scalar("alpha_v", 0.1f);
        } else {
            r.alpha_u = r.alpha_v = textures.scalar("alpha", 0.1f);
        }
        if (!(r.alpha_u.min_value() >= 0.f) || !(r.alpha_v.min_value() >= 0.f) ||
            !std::isfinite(r.alpha_u.max_value()) || !std::isfinite(r.alpha_v.max_value()))
            throw InputError(obj.loc, "roughness alpha must be finite and non-negative");
        return r;
    }

    BsdfModel build_bsdf_model(const ObjectDesc& obj) {
        Properties props(obj, diagnostics);
        TextureParams textures(*this, obj, props);
        BsdfModel model;
        if (obj.type == "diffuse") {
            model = DiffuseBsdf{textures.rgb("reflectance", Rgb::Constant(0.5f))};
        } else if (obj.type == "dielectric" || obj.type == "thindielectric" ||
                   obj.type == "roughdielectric") {
            const float int_ior = read_ior(props, "int_ior", 1.5046f);
            const float ext_ior = read_ior(props, "ext_ior", 1.000277f);
            const RgbTexture r = textures.rgb("specular_reflectance", Rgb::Ones());
            const RgbTexture t = textures.rgb("specular_transmittance", Rgb::Ones());
            if (obj.type == "dielectric") {
                model = DielectricBsdf{int_ior / ext_ior, r, t};
            } else if (obj.type == "thindielectric") {
                model = ThinDielectricBsdf{int_ior / ext_ior, r, t};
            } else {
                if (int_ior == ext_ior)
                    throw InputError(obj.loc, "roughdielectric: int_ior and ext_ior must differ");
                model = RoughDielectricBsdf{read_roughness(props, textures, obj), int_ior / ext_ior,
                                            r, t};
            }
        } else if (obj.type == "conductor" || obj.type == "roughconductor") {
            Rgb eta = Rgb::Zero(), k = Rgb::Ones();
            bool perfect_mirror = true;
            read_conductor_ior(props, &eta, &k, &perfect_mirror);
            const RgbTexture r = textures.rgb("specular_reflectance", Rgb::Ones());
            if (obj.type == "conductor")
                model = ConductorBsdf{eta, k, perfect_mirror, r};
            else
                model = RoughConductorBsdf{read_roughness(props, textures, obj), eta, k,
                                           perfect_mirror, r};
        } else if (obj.type == "plastic" || obj.type == "roughplastic") {
            // Mitsuba's defaults: polypropylene (1.49) in air.
            const float int_ior = read_ior(props, "int_ior", 1.49f);
            const float ext_ior = read_ior(props, "ext_ior", 1.000277f);
            if (int_ior == ext_ior)
                throw InputError(obj.loc, obj.type + ": int_ior and ext_ior must differ");
            RgbTexture diffuse = textures.rgb("diffuse_reflectance", Rgb::Constant(0.5f));
            RgbTexture specular = textures.rgb("specular_reflectance", Rgb::Ones());
            const bool nonlinear = props.get_bool("nonlinear", false);
            if (obj.type == "plastic") {
                model = make_plastic(int_ior / ext_ior, std::move(diffuse), std::move(specular),
                                     nonlinear);
            } else {
                // Mitsuba's roughplastic is isotropic with a scalar alpha (its coat tables are
                // precomputed per material); alpha_u / alpha_v are reported as unknown.
                const MicrofacetType type = read_distribution(props);
                const auto alpha = static_cast<float>(props.get_float("alpha", 0.1));
                if (!(alpha >= 0.f) || !std::isfinite(alpha))
                    throw InputError(props.loc_of("alpha"),
                                     "alpha must be finite and non-negative");
                const bool visible = props.get_bool("sample_visible", true);
                model = make_rough_plastic(type, alpha, visible, int_ior / ext_ior,
                                           std::move(diffuse), std::move(specular), nonlinear);
            }
        } else {
            diagnostics.unknown(obj.loc, "unknown BSDF '" + obj.type +
                                             "' (supported: diffuse, dielectric, thindielectric, "
                                             "roughdielectric, conductor, roughconductor, plastic, "
                                             "roughplastic, twosided, mask, blendbsdf, null, "
                                             "normalmap)");
            model = DiffuseBsdf{};
        }
        props.check_all_used();
        textures.check_all_used();
        return model;
    }

    /// The BSDF plugins built as Bsdf composites (wrappers of other BSDFs).
    static bool is_composite_bsdf_type(const std::string& type) {
        return type == "mask" || type == "blendbsdf" || type == "null" || type == "normalmap" ||
               type == "bumpmap";
    }

    /// Mitsuba's `mask`, `blendbsdf`, `null`, `normalmap` and `bumpmap` (see Bsdf's
    /// composites).
    Bsdf build_composite_bsdf(const ObjectDesc& obj) {
        Properties props(obj, diagnostics);
        TextureParams textures(*this, obj, props);
        std::vector<Bsdf> nested;
        for (const ChildRef* child : textures.nested_bsdfs())
            nested.push_back(build_bsdf(object(child->object)));
        Bsdf bsdf;
        if (obj.type == "null") {
            if (!nested.empty()) throw InputError(obj.loc, "null takes no nested BSDF");
            bsdf = Bsdf::null();
        } else if (obj.type == "normalmap") {
            if (nested.size() != 1) throw InputError(obj.loc, "normalmap expects one nested BSDF");
            if (!textures.has("normalmap"))
                throw InputError(obj.loc, "normalmap needs a 'normalmap' texture");
            RgbTexture normals =
                textures.rgb("normalmap", Rgb(0.5f, 0.5f, 1.f), SpectrumUse::Unbounded);
            const bool flip = props.get_bool("flip_invalid_normals", true);
            const bool shadowing = props.get_bool("use_shadowing_function", true);
            bsdf = Bsdf::normal_map(std::move(normals), std::move(nested[0]), flip, shadowing);
        } else if (obj.type == "bumpmap") {
            // Mitsuba 3: one nested BSDF and one nested texture, whatever its name.
            if (nested.size() != 1) throw InputError(obj.loc, "bumpmap expects one nested BSDF");
            const std::vector<const ChildRef*> heights = textures.nested_textures();
            if (heights.size() != 1)
                throw InputError(obj.loc, "bumpmap expects one nested texture (the height)");
            RgbTexture height = build_texture(object(heights[0]->object));
            const auto scale = static_cast<float>(props.get_float("scale", 1.0));
            if (!std::isfinite(scale))
                throw InputError(props.loc_of("scale"), "bumpmap: scale must be finite");
            const bool flip = props.get_bool("flip_invalid_normals", true);
            const bool shadowing = props.get_bool("use_shadowing_function", true);
            bsdf = Bsdf::bump_map(std::move(height), scale, std::move(nested[0]), flip, shadowing);
        } else if (obj.type == "mask") {
            if (nested.size() != 1) throw InputError(obj.loc, "mask expects one nested BSDF");
            bsdf = Bsdf::mask(textures.scalar("opacity", 0.5f), std::move(nested[0]));
        } else {
            if (nested.size() != 2) throw InputError(obj.loc, "blendbsdf expects two nested BSDFs");
            if (!textures.has("weight"))
                throw InputError(obj.loc, "blendbsdf needs a 'weight' (a float or a texture)");
            bsdf = Bsdf::blend(textures.scalar("weight", 0.5f), std::move(nested[0]),
                               std::move(nested[1]));
        }
        props.check_all_used();
        textures.check_all_used();
        return bsdf;
    }

    Bsdf build_bsdf(const ObjectDesc& obj) {
        if (is_composite_bsdf_type(obj.type)) return build_composite_bsdf(obj);
        if (obj.type != "twosided") return Bsdf(build_bsdf_model(obj));
        Properties(obj, diagnostics).check_all_used();
        std::vector<BsdfModel> nested;
        for (const ChildRef& child : obj.children) {
            const ObjectDesc& c = object(child.object);
            if (c.tag != "bsdf") throw InputError(c.loc, "twosided expects nested <bsdf> elements");
            if (c.type == "twosided") throw InputError(c.loc, "twosided cannot nest twosided");
            if (is_composite_bsdf_type(c.type))
                throw InputError(c.loc, "twosided cannot wrap " + c.type +
                                            " (write the twosided inside the " + c.type + ")");
            nested.push_back(build_bsdf_model(c));
        }
        if (nested.empty() || nested.size() > 2)
            throw InputError(obj.loc, "twosided expects one or two nested BSDFs");
        for (const BsdfModel& m : nested)
            if (Bsdf(m).has_transmission())
                throw InputError(obj.loc, "twosided cannot wrap a transmissive BSDF");
        std::optional<BsdfModel> back;
        if (nested.size() == 2) back = nested[1];
        return Bsdf::two_sided(nested[0], back);
    }

    int bsdf_index(int object_index) {
        const auto it = bsdf_of_object.find(object_index);
        if (it != bsdf_of_object.end()) return it->second;
        const ObjectDesc& obj = object(object_index);
        bsdfs.push_back(build_bsdf(obj));
        std::string kind = obj.type;
        if (kind == "twosided" && !obj.children.empty())
            kind = object(obj.children.front().object).type;
        bsdf_kind.push_back(obj.type == "twosided" ? "twosided(" + kind + ")" : kind);
        const int index = static_cast<int>(bsdfs.size()) - 1;
        bsdf_of_object[object_index] = index;
        return index;
    }

    int default_bsdf() {
        // Mitsuba gives shapes without a BSDF a diffuse one with reflectance 0.5.
        constexpr int kDefault = -2;
        const auto it = bsdf_of_object.find(kDefault);
        if (it != bsdf_of_object.end()) return it->second;
        bsdfs.emplace_back(DiffuseBsdf{});
        bsdf_kind.push_back("diffuse");
        const int index = static_cast<int>(bsdfs.size()) - 1;
        bsdf_of_object[kDefault] = index;
        return index;
    }

    /// Mitsuba 3's cylinder: `p0`, `p1`, `radius` (negative: normals flipped) and to_world,
    /// which must keep the cross-section round and unsheared (Mitsuba only warns; its sampling
    /// and area then assume a round one anyway).
    Cylinder read_cylinder(Properties& props, const Transform& to_world, bool flip_normals) {
        double radius = props.get_float("radius", 1.0);
        const Vec3d p0 = props.get_vec3("p0", Vec3d::Zero());
        const Vec3d p1 = props.get_vec3("p1", Vec3d(0.0, 0.0, 1.0));
        if (!(radius != 0.0) || !std::isfinite(radius))
            throw InputError(props.loc_of("radius"), "cylinder radius must be non-zero and finite");
        if (radius < 0.0) {
            radius = -radius;
            flip_normals = !flip_normals;
        }
        const Vec3d axis = p1 - p0;
        const double axis_length = axis.norm();
        if (!(axis_length > 0.0) || !std::isfinite(axis_length))
            throw InputError(props.loc_of("p1"), "cylinder p0 and p1 must differ");
        // to_world * translate(p0) * to_frame(axis) * scale(radius, radius, length), as Mitsuba 3.
        const Frame frame = Frame::from_normal((axis / axis_length).cast<float>());
        Eigen::Matrix3d local;
        local.col(0) = frame.s.cast<double>() * radius;
        local.col(1) = frame.t.cast<double>() * radius;
        local.col(2) = axis;
        const Eigen::Matrix3d to_world_linear = to_world.matrix.topLeftCorner<3, 3>();
        const Eigen::Matrix3d linear = to_world_linear * local;
        const Vec3d origin = to_world.apply_point(p0);
        const double rx = linear.col(0).norm(), ry = linear.col(1).norm(),
                     length = linear.col(2).norm();
        const auto perpendicular = [](const Vec3d& a, const Vec3d& b) {
            return std::abs(a.dot(b)) <= 1e-5 * a.norm() * b.norm();
        };
        if (!(rx > 0.0) || !(length > 0.0) || std::abs(rx - ry) > 1e-5 * rx ||
            !perpendicular(linear.col(0), linear.col(1)) ||
            !perpendicular(linear.col(0), linear.col(2)) ||
            !perpendicular(linear.col(1), linear.col(2)))
            throw InputError(props.loc_of("to_world"),
                             "cylinder to_world must keep the cross-section round (no shear, the "
                             "same scale across the axis)");
        check_world_point(Vec3d(origin.array().abs() + rx + length), props.loc_of("to_world"),
                          "the cylinder");
        Cylinder c;
        c.origin = origin.cast<float>();
        c.linear = linear.cast<float>();
        c.object_from_world = linear.inverse().cast<float>();
        c.radius = static_cast<float>(rx);
        c.length = static_cast<float>(length);
        c.flip_normals = flip_normals;
        return c;
    }

    /// Mitsuba 3's `instance` of a `shapegroup`: the group's shapes, each with the instance's
    /// to_world applied after its own. A group's meshes are built once, in the group's space,
    /// and every instance places them as MeshInstance shapes that Embree traces as instances
    /// (memory does not grow with triangles times instances); its spheres and cylinders, a few
    /// numbers each, are built as shapes of their own with the composed transform.
    void build_instance(const ObjectDesc& obj) {
        Properties props(obj, diagnostics);
        const Transform world_from_instance = props.get_transform("to_world");
        props.check_all_used();
        const ObjectDesc* group = nullptr;
        for (const ChildRef& child : obj.children) {
            const ObjectDesc& c = object(child.object);
            if (c.tag == "shape" && c.type == "shapegroup" && !group)
                group = &c;
            else
                throw InputError(child.loc,
                                 "an instance takes one shapegroup (got " + describe(c) + ")");
        }
        if (!group) throw InputError(obj.loc, "an instance needs a <ref> to a shapegroup");
        Properties(*group, diagnostics).check_all_used();
        for (const ChildRef& child : group->children) {
            const ObjectDesc& c = object(child.object);
            if (c.tag != "shape" || c.type == "shapegroup" || c.type == "instance")
                throw InputError(child.loc, "a shapegroup holds shapes only (not " + describe(c) +
                                                "; nested instancing is not supported)");
            for (const ChildRef& grandchild : c.children)
                if (object(grandchild.object).tag == "emitter")
                    throw InputError(grandchild.loc,
                                     "a shape in a shapegroup cannot emit (as in Mitsuba 3)");
            if (c.type == "sphere" || c.type == "cylinder")
                build_shape(c, &world_from_instance);
            else
                place_group_mesh(child.object, world_from_instance, props.loc_of("to_world"));
        }
        ++counts["instances"];
        features.shape_kinds.insert("instance");
    }

    /// A shapegroup's mesh (object `object_index`), built once in the group's space, placed in
    /// the scene by an instance's to_world.
    void place_group_mesh(int object_index, const Transform& world_from_instance,
                          const FileLoc& loc) {
        GroupMesh& group_mesh = group_meshes[object_index];
        if (!group_mesh.shape) {
            const ObjectDesc* emitter_desc = nullptr;  // refused before this
            std::optional<Shape> built = make_shape(object(object_index), nullptr, emitter_desc);
            if (!built || !built->is_mesh()) return;  // an unknown shape under --lenient
            group_mesh.shape = std::make_shared<const Shape>(std::move(*built));
            for (const Vec3f& p : std::get<TriangleMesh>(group_mesh.shape->geometry()).positions)
                group_mesh.box.extend(p.cast<double>());
        }
        const std::shared_ptr<const Shape>& object_mesh = group_mesh.shape;
        const Eigen::Matrix3d linear = world_from_instance.matrix.topLeftCorner<3, 3>();
        if (!(std::abs(linear.determinant()) > 0.0))
            throw InputError(loc, "an instance's to_world must be invertible");
        MeshInstance instance(object_mesh, linear.cast<float>(),
                              world_from_instance.matrix.topRightCorner<3, 1>().cast<float>());
        // Its world box's corners must lie where a flattened copy's vertices may.
        for (int corner = 0; corner < 8; ++corner)
            check_world_point(world_from_instance.apply_point(Vec3d(group_mesh.box.corner(
                                  static_cast<Eigen::AlignedBox3d::CornerType>(corner)))),
                              loc, "a vertex of an instance of " + describe(object(object_index)));
        counts["instanced_triangles"] += instance.mesh().triangle_count();
        shapes.emplace_back(std::move(instance), object_mesh->bsdf(), object_mesh->id());
    }

    /// `obj` built as a Shape (not added to the scene's; null for an unknown shape under
    /// --lenient), with `outer` applied after its own to_world; its area emitter's element, if
    /// it has one, in `emitter_desc`.
    std::optional<Shape> make_shape(const ObjectDesc& obj, const Transform* outer,
                                    const ObjectDesc*& emitter_desc) {
        Properties props(obj, diagnostics);

        const Transform world_from_object =
            outer ? Transform(Mat4d(outer->matrix * props.get_transform("to_world").matrix))
                  : props.get_transform("to_world");
        const bool flip_normals = props.get_bool("flip_normals", false);
        std::optional<Shape> shape;

        int bsdf = -1;
        for (const ChildRef& child : obj.children) {
            const ObjectDesc& c = object(child.object);
            if (c.tag == "bsdf") {
                if (bsdf >= 0) throw InputError(child.loc, "a shape can have only one BSDF");
                bsdf = bsdf_index(child.object);
            } else if (c.tag == "emitter") {
                if (c.type != "area")
                    throw InputError(c.loc, "only area emitters can be attached to a shape");
                if (emitter_desc) throw InputError(child.loc, "a shape can have only one emitter");
                emitter_desc = &c;
            } else {
                diagnostics.unknown(c.loc, "unsupported element " + describe(c) + " in <shape>");
            }
        }
        if (bsdf < 0) bsdf = default_bsdf();

        if (obj.type == "sphere") {
            const Vec3d center_object = props.get_vec3("center", Vec3d::Zero());
            const double radius_object = props.get_float("radius", 1.0);
            if (!(radius_object > 0.0))
                throw InputError(props.loc_of("radius"), "sphere radius must be positive");
            // A similarity has L^T L = s^2 I; anything else would make an ellipsoid.
            const Eigen::Matrix3d linear = world_from_object.matrix.topLeftCorner<3, 3>();
            const double scale = std::cbrt(std::abs(linear.determinant()));
            const Eigen::Matrix3d gram = linear.transpose() * linear / (scale * scale);
            if (!(scale > 0.0) || (gram - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-5)
                throw InputError(
                    props.loc_of("to_world"),
                    "sphere to_world must be a similarity (uniform scale, rotation, translation)");
            Sphere s;
            const Vec3d center = world_from_object.apply_point(center_object);
            const double radius = radius_object * scale;
            check_world_point(Vec3d(center.array().abs() + radius), props.loc_of("radius"),
                              "the sphere");
            s.center = center.cast<float>();
            s.radius = static_cast<float>(radius);
            s.flip_normals = flip_normals;
            shape.emplace(s, bsdf, obj.id);
        } else if (obj.type == "cylinder") {
            shape.emplace(read_cylinder(props, world_from_object, flip_normals), bsdf, obj.id);
        } else {
            TriangleMesh mesh;
            bool face_normals = true;
            if (obj.type == "rectangle") {
                mesh = make_rectangle();
            } else if (obj.type == "cube") {
                mesh = make_cube();
            } else if (obj.type == "disk") {
                mesh = make_disk();
            } else if (obj.type == "obj" || obj.type == "ply" || obj.type == "off" ||
                       obj.type == "serialized") {
                const std::string filename = props.get_string("filename", "");
                if (filename.empty())
                    throw InputError(obj.loc, describe(obj) + " needs a 'filename'");
                // A .serialized file may hold several meshes (Mitsuba's shape_index).
                const int shape_index =
                    obj.type == "serialized" ? props.get_int32("shape_index", 0) : 0;
                if (shape_index < 0)
                    throw InputError(props.loc_of("shape_index"), "shape_index must be >= 0");
                TriangleMeshData data = load_mesh(filename, props.loc_of("filename"), shape_index);
                face_normals = props.get_bool("face_normals", false) || data.face_normals;
                props.ignore("flip_tex_coords");
                counts["degenerate_triangles_dropped"] += data.degenerate_triangles_dropped;
                mesh.positions = std::move(data.positions);
                mesh.uvs = std::move(data.uvs);
                mesh.indices = std::move(data.indices);
                for (MeshAttribute& attribute : data.attributes)
                    mesh.attributes.push_back(
                        std::make_shared<const MeshAttribute>(std::move(attribute)));
                if (!face_normals) {
                    mesh.normals = data.normals.empty()
                                       ? compute_vertex_normals(TriangleMeshData{
                                             mesh.positions, {}, {}, mesh.indices, 0, false, {}})
                                       : std::move(data.normals);
                }
            } else {
                diagnostics.unknown(
                    obj.loc, "unknown shape '" + obj.type +
                                 "' (supported: obj, ply, off, serialized, rectangle, cube, disk, "
                                 "sphere, cylinder, shapegroup and instance)");
                return std::nullopt;
            }
            mesh.flip_normals = flip_normals;
            transform_mesh(mesh, world_from_object);
            for (const Vec3f& position : mesh.positions)
                check_world_point(position.cast<double>(), props.loc_of("to_world"),
                                  "a vertex of " + describe(obj));
            counts["triangles"] += mesh.triangle_count();
            shape.emplace(std::move(mesh), bsdf, obj.id);
        }
        props.check_all_used();
        features.shape_kinds.insert(obj.type);
        return shape;
    }

    /// One shape, added to the scene's; `outer` (an instance's to_world) applies after the
    /// shape's own to_world.
    void build_shape(const ObjectDesc& obj, const Transform* outer = nullptr) {
        const ObjectDesc* emitter_desc = nullptr;
        std::optional<Shape> shape = make_shape(obj, outer, emitter_desc);
        if (!shape) return;
        const int shape_index = static_cast<int>(shapes.size());
        if (emitter_desc) {
            if (!(shape->surface_area() > 0.f))
                throw InputError(emitter_desc->loc, "area emitter on a shape of zero area");
            shape->set_emitter(static_cast<int>(emitters.size()));
            build_emitter(*emitter_desc, shape_index);
        }
        shapes.push_back(std::move(*shape));
    }

    /// The rotation part of an emitter's to_world (directions only); rejects scales and shears,
    /// which would distort directional densities.
    static Mat3f read_rotation(Properties& props, const Transform& to_world) {
        const Eigen::Matrix3d linear = to_world.matrix.topLeftCorner<3, 3>();
        if ((linear.transpose() * linear - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() >
            1e-4)
            throw InputError(props.loc_of("to_world"),
                             "to_world of this emitter must be a rotation (no scale)");
        return linear.cast<float>();
    }

    bool referenced_by_any(int object_index) const {
        for (const ObjectDesc& o : desc.objects)
            for (const ChildRef& c : o.children)
                if (c.object == object_index && &o != &desc.root_object()) return true;
        return false;
    }

    bool referenced_by_a_shape(int object_index) const {
        for (const ObjectDesc& o : desc.objects)
            if (o.tag == "shape")
                for (const ChildRef& c : o.children)
                    if (c.object == object_index) return true;
        return false;
    }

    void build_emitter(const ObjectDesc& obj, int shape_index) {
        Properties props(obj, diagnostics);
        TextureParams textures(*this, obj, props);
        if (obj.type == "area") {
            if (shape_index < 0)
                throw InputError(obj.loc, "an area emitter must be nested in a <shape>");
            emitters.emplace_back(AreaEmitter{
                textures.rgb("radiance", Rgb::Ones(), SpectrumUse::Emission), shape_index});
            features.has_area_emitters = true;
        } else if (obj.type == "point") {
            PointEmitter p;
            const Transform to_world = props.get_transform("to_world");
            const Vec3d position = props.get_vec3("position", Vec3d::Zero());
            check_world_point(to_world.apply_point(position), props.loc_of("position"),
                              "the point light");
            p.position = to_world.apply_point(position).cast<float>();
            p.intensity = props.get_rgb("intensity", Rgb::Ones(), true, SpectrumUse::Emission);
            emitters.emplace_back(p);
            features.has_delta_emitters = true;
        } else if (obj.type == "spot") {
            const Transform to_world = props.get_transform("to_world");
            const Mat3f rotation = read_rotation(props, to_world);
            const auto cutoff = static_cast<float>(props.get_float("cutoff_angle", 20.0));
            const auto beam = static_cast<float>(props.get_float("beam_width", 0.75 * cutoff));
            if (!(cutoff > 0.f && cutoff <= 180.f))
                throw InputError(props.loc_of("cutoff_angle"),
                                 "cutoff_angle must be in (0, 180] degrees");
            if (!(beam >= 0.f && beam <= cutoff))
                throw InputError(props.loc_of("beam_width"),
                                 "beam_width must be in [0, cutoff_angle]");
            check_world_point(to_world.apply_point(Vec3d(Vec3d::Zero())), props.loc_of("to_world"),
                              "the spot light");
            const Vec3f position = to_world.apply_point(Vec3d(Vec3d::Zero())).cast<float>();
            std::optional<RgbTexture> texture;
            if (textures.has("texture")) {
                texture = textures.rgb("texture", Rgb::Ones(), SpectrumUse::Reflectance);
                features.has_textures = true;
            }
            emitters.emplace_back(
                make_spot(position, rotation,
                          props.get_rgb("intensity", Rgb::Ones(), true, SpectrumUse::Emission),
                          cutoff, beam, std::move(texture)));
            features.has_delta_emitters = true;
        } else if (obj.type == "projector") {
            // Mitsuba 3's projector (its parameters: irradiance, scale, to_world and the
            // perspective camera's fov, fov_axis, focal_length): the texture's pixels are the
            // film of a pinhole camera that projects them.
            if (!textures.has("irradiance"))
                throw InputError(obj.loc, "projector: an irradiance texture is required");
            RgbTexture irradiance =
                textures.rgb("irradiance", Rgb::Ones(), SpectrumUse::Reflectance);
            int width = 1, height = 1;
            if (const auto* bitmap = std::get_if<BitmapTexture>(&irradiance.model())) {
                width = bitmap->data->width;
                height = bitmap->data->height;
            }
            const auto [fov, fov_axis] = read_fov(props);
            const Transform to_world = props.get_transform("to_world");
            check_world_point(to_world.apply_point(Vec3d(Vec3d::Zero())), props.loc_of("to_world"),
                              "the projector");
            ProjectorEmitter projector;
            projector.scale = static_cast<float>(props.get_float("scale", 1.0));
            if (!(projector.scale >= 0.f) || !std::isfinite(projector.scale))
                throw InputError(props.loc_of("scale"), "scale must be finite and >= 0");
            Film film;
            film.width = film.crop_width = width;
            film.height = film.crop_height = height;
            film.filter = PixelFilter();  // box: the film only maps directions here
            projector.camera = Camera(to_world, film, fov, fov_axis, 1e-4f);
            projector.irradiance = std::move(irradiance);
            projector.axis = to_world.apply_vector(Vec3d(0.0, 0.0, 1.0)).normalized().cast<float>();
            emitters.emplace_back(std::move(projector));
            features.has_delta_emitters = true;
            features.has_textures = true;
        } else if (obj.type == "directional") {
            DirectionalEmitter d;
            if (props.has("direction") && props.has("to_world"))
                throw InputError(obj.loc,
                                 "directional: give either direction or to_world, not both");
            Vec3d direction = props.get_vec3("direction", Vec3d(0.0, 0.0, 1.0));
            if (props.has("to_world"))
                direction = props.get_transform("to_world").apply_vector(Vec3d(0.0, 0.0, 1.0));
            if (!(direction.norm() > 0.0)) throw InputError(obj.loc, "directional: zero direction");
            d.direction = direction.normalized().cast<float>();
            d.irradiance = props.get_rgb("irradiance", Rgb::Ones(), true, SpectrumUse::Emission);
            emitters.emplace_back(d);
            features.has_delta_emitters = true;
        } else if (obj.type == "constant") {
            emitters.emplace_back(ConstantEmitter{
                props.get_rgb("radiance", Rgb::Ones(), true, SpectrumUse::Emission)});
            features.has_infinite_emitters = true;
        } else if (obj.type == "envmap") {
            const std::string filename = props.get_string("filename", "");
            if (filename.empty()) throw InputError(obj.loc, "envmap needs a 'filename'");
            EnvmapEmitter e;
            const Mat3f rotation = read_rotation(props, props.get_transform("to_world"));
            e.world_from_local = rotation;
            e.local_from_world = rotation.transpose();
            e.scale = static_cast<float>(props.get_float("scale", 1.0));
            if (!(e.scale >= 0.f) || !std::isfinite(e.scale))
                throw InputError(props.loc_of("scale"), "scale must be finite and non-negative");
            try {
                // Environment images are radiance: always linear (Mitsuba converts them with
                // its file's own encoding; HDR and EXR are linear).
                BitmapData image = load_bitmap(filename, false);
                e.data = std::make_shared<const EnvmapData>(
                    make_envmap_data(image.width, image.height, std::move(image.texels)));
            } catch (const InputError& error) {
                throw InputError(props.loc_of("filename"), error.what());
            } catch (const std::invalid_argument& error) {
                throw InputError(props.loc_of("filename"), filename + ": " + error.what());
            }
            emitters.emplace_back(std::move(e));
            features.has_infinite_emitters = true;
            features.has_textures = true;
        } else {
            diagnostics.unknown(
                obj.loc,
                "unknown emitter '" + obj.type +
                    "' (supported: area, point, spot, directional, constant, envmap, projector)");
            return;
        }
        features.emitter_kinds.insert(obj.type);
        props.check_all_used();
        textures.check_all_used();
        counts["emitters"] += 1;
    }

    void compute_features() {
        std::set<int> used;
        for (const Shape& s : shapes) used.insert(s.bsdf());
        for (int index : used) {
            const Bsdf& b = bsdfs[static_cast<std::size_t>(index)];
            features.bsdf_kinds.insert(bsdf_kind[static_cast<std::size_t>(index)]);
            const BsdfLobes l = b.lobes();
            const bool glossy_lobe = l.glossy_reflection || l.glossy_transmission;
            if (l.diffuse_reflection || b.roughness_class() == RoughnessClass::Diffuse)
                features.has_diffuse = true;
            // A microfacet lobe counts by its class: glossy, or delta-like below the threshold.
            if (l.sharpest_class == RoughnessClass::Glossy && glossy_lobe)
                features.has_glossy = true;
            const bool delta_like = l.sharpest_class == RoughnessClass::Delta;
            if (l.delta_reflection || (delta_like && l.glossy_reflection))
                features.has_delta_reflection = true;
            if (l.delta_transmission || (delta_like && l.glossy_transmission))
                features.has_delta_transmission = true;
            if (b.has_transmission()) features.has_transmission = true;
        }
        features.specular_chains_possible =
            features.has_delta_reflection || features.has_delta_transmission || features.has_glossy;
        counts["shapes"] = shapes.size();
        counts["bsdfs"] = bsdfs.size();
    }
};

}  // namespace

Scene build_scene(const SceneDesc& desc, const BuildOptions& options) {
    Builder b{
        desc, Diagnostics(options.lenient), {}, {}, {}, {}, {}, {}, false, {}, {}, {}, {}, {}, {},
        {}};
    b.build_root();
    b.bind_mesh_attributes();
    b.compute_features();
    if (b.emitters.empty())
        std::cerr << desc.scene_file
                  << ": warning: the scene has no emitters; the image will be black\n";
    return Scene(std::move(b.shapes), std::move(b.bsdfs), std::move(b.emitters), b.camera,
                 std::move(b.integrator), b.sampler, std::move(b.features), std::move(b.counts));
}

}  // namespace gdmlt
