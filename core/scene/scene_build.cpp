// SPDX-License-Identifier: GPL-3.0-or-later
// SceneDesc -> Scene: plugin validation, property reading with unknown-property detection
// (pbrt-v4's ReportUnused, Mitsuba's unqueried-property error), mesh loading, transforms.
#include <filesystem>
#include <iostream>
#include <set>

#include "core/geometry/mesh_io.h"
#include "core/image/image_io.h"
#include "core/math/transform.h"
#include "core/scene/scene.h"

namespace gdmlt {
namespace {

std::string describe(const ObjectDesc& obj) {
    return "<" + obj.tag + " type=\"" + obj.type + "\">";
}

const char* value_kind(const PropertyValue& v) {
    switch (v.index()) {
        case 0: return "boolean";
        case 1: return "integer";
        case 2: return "float";
        case 3: return "string";
        case 4: return "rgb";
        case 5: return "point/vector";
        case 6: return "transform";
        case 7: return "spectrum";
    }
    return "?";
}

/// Reports problems that --lenient may turn into warnings.
class Diagnostics {
public:
    explicit Diagnostics(bool lenient) : lenient_(lenient) {}
    void unknown(const FileLoc& loc, const std::string& message) const {
        if (!lenient_) throw InputError(loc, message);
        std::cerr << loc.to_string() << ": warning: " << message << " (ignored: --lenient)\n";
    }
    void warn(const FileLoc& loc, const std::string& message) const {
        std::cerr << loc.to_string() << ": warning: " << message << "\n";
    }
    bool lenient() const { return lenient_; }

private:
    bool lenient_;
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
    /// An RGB quantity: <rgb>, <srgb> (linearised), <spectrum value="v"> or <float>.
    /// `non_negative`: negative components are an error (reflectances, radiances).
    Rgb get_rgb(const std::string& name, const Rgb& fallback, bool non_negative = true) {
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
            value = Rgb::Constant(parse_constant_spectrum(*p, s->text));
        } else {
            throw mismatch(*p, "rgb, spectrum or float");
        }
        if (!is_finite(value)) throw InputError(p->loc, "'" + name + "' is not finite");
        if (non_negative && (value < 0.f).any())
            throw InputError(p->loc, "'" + name + "' must not be negative");
        return value;
    }
    /// A texture-capable RGB parameter (only constants so far: a nested <texture> is reported).
    RgbTexture get_texture(const std::string& name, const Rgb& fallback) {
        return RgbTexture(get_rgb(name, fallback));
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
    static float parse_constant_spectrum(const Property& p, const std::string& text) {
        std::size_t consumed = 0;
        float v = 0.f;
        try {
            v = std::stof(text, &consumed);
        } catch (const std::exception&) {
            consumed = 0;
        }
        if (consumed == 0 || text.find_first_not_of(" \t", consumed) != std::string::npos)
            throw InputError(p.loc, "only constant spectra are supported (got \"" + text + "\")");
        return v;
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
    if (world_from_object.flips_handedness())
        for (std::size_t t = 0; t + 2 < mesh.indices.size(); t += 3)
            std::swap(mesh.indices[t + 1], mesh.indices[t + 2]);
}

struct Builder {
    const SceneDesc& desc;
    Diagnostics diagnostics;

    std::vector<Shape> shapes;
    std::vector<Bsdf> bsdfs;
    std::vector<Emitter> emitters;
    std::map<int, int> bsdf_of_object;  // SceneDesc object index -> bsdfs index
    std::vector<std::string> bsdf_kind;  // per bsdfs entry, for SceneFeatures
    PerspectiveCamera camera;
    bool has_camera = false;
    IntegratorSettings integrator;
    SamplerSettings sampler;
    SceneFeatures features;
    std::map<std::string, std::size_t> counts;

    const ObjectDesc& object(int index) const { return desc.objects.at(static_cast<std::size_t>(index)); }

    void build_root() {
        const ObjectDesc& root = desc.root_object();
        for (const ChildRef& child : root.children) {
            const ObjectDesc& obj = object(child.object);
            if (obj.tag == "shape") {
                build_shape(obj);
            } else if (obj.tag == "bsdf") {
                bsdf_index(child.object);  // declared for later refs; built once
            } else if (obj.tag == "emitter") {
                build_emitter(obj, -1);
            } else if (obj.tag == "sensor") {
                if (has_camera) throw InputError(obj.loc, "only one <sensor> is supported");
                build_sensor(obj);
            } else if (obj.tag == "integrator") {
                build_integrator(obj);
            } else if (obj.tag == "texture") {
                diagnostics.unknown(obj.loc, "textures are not supported yet: " + describe(obj));
            } else {
                diagnostics.unknown(obj.loc, "unsupported element " + describe(obj) + " in <scene>");
            }
        }
        if (!has_camera) {
            // Mitsuba adds a default perspective sensor; so do we, with its film defaults.
            Film film;
            film.crop_width = film.width;
            film.crop_height = film.height;
            camera = PerspectiveCamera(Transform(), film, 45.f, "x", 0.01f);
        }
    }

    void build_integrator(const ObjectDesc& obj) {
        static const std::set<std::string> known = {"path", "pssmlt", "gdpt", "gdmlt"};
        integrator.desc = obj;
        integrator.type = obj.type;
        if (!known.count(obj.type)) {
            diagnostics.unknown(obj.loc, "unknown integrator '" + obj.type +
                                             "' (supported: path, pssmlt, gdpt, gdmlt)");
            integrator.type = "path";
        }
        Properties props(obj, diagnostics);
        integrator.max_depth = static_cast<int>(props.get_int("max_depth", -1));
        integrator.rr_depth = static_cast<int>(props.get_int("rr_depth", 5));
        integrator.hide_emitters = props.get_bool("hide_emitters", false);
        if (integrator.max_depth < -1 || integrator.max_depth == 0)
            throw InputError(props.loc_of("max_depth"), "max_depth must be -1 or at least 1");
        if (integrator.rr_depth < 1)
            throw InputError(props.loc_of("rr_depth"), "rr_depth must be at least 1");
        // The other integrators validate their own properties; the path tracer knows all of its.
        if (obj.type == "path") props.check_all_used();
    }

    void build_sensor(const ObjectDesc& obj) {
        if (obj.type != "perspective")
            throw InputError(obj.loc, "unsupported sensor '" + obj.type + "' (supported: perspective)");
        Properties props(obj, diagnostics);
        const auto fov = static_cast<float>(props.get_float("fov", 39.3077));
        const std::string fov_axis = props.get_string("fov_axis", "x");
        const auto near_clip = static_cast<float>(props.get_float("near_clip", 0.01));
        props.ignore("far_clip");
        const Transform world_from_camera = props.get_transform("to_world");
        if (!(fov > 0.f && fov < 180.f)) throw InputError(props.loc_of("fov"), "fov must be in (0, 180)");
        static const std::set<std::string> axes = {"x", "y", "diagonal", "smaller", "larger"};
        if (!axes.count(fov_axis))
            throw InputError(props.loc_of("fov_axis"), "fov_axis must be x, y, diagonal, smaller or larger");
        props.check_all_used();

        Film film;
        film.crop_width = film.width;
        film.crop_height = film.height;
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
        camera = PerspectiveCamera(world_from_camera, film, fov, fov_axis, near_clip);
        has_camera = true;
    }

    Film build_film(const ObjectDesc& obj) {
        if (obj.type != "hdrfilm")
            diagnostics.unknown(obj.loc, "unsupported film '" + obj.type + "' (supported: hdrfilm)");
        Properties props(obj, diagnostics);
        Film film;
        film.width = static_cast<int>(props.get_int("width", 768));
        film.height = static_cast<int>(props.get_int("height", 576));
        if (film.width < 1 || film.height < 1 || film.width > 1 << 16 || film.height > 1 << 16)
            throw InputError(obj.loc, "film size must be between 1 and 65536 pixels");
        film.crop_offset_x = static_cast<int>(props.get_int("crop_offset_x", 0));
        film.crop_offset_y = static_cast<int>(props.get_int("crop_offset_y", 0));
        film.crop_width = static_cast<int>(props.get_int("crop_width", film.width - film.crop_offset_x));
        film.crop_height = static_cast<int>(props.get_int("crop_height", film.height - film.crop_offset_y));
        if (film.crop_offset_x < 0 || film.crop_offset_y < 0 || film.crop_width < 1 ||
            film.crop_height < 1 || film.crop_offset_x + film.crop_width > film.width ||
            film.crop_offset_y + film.crop_height > film.height)
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
                has_filter = true;
                if (c.type != "box")
                    diagnostics.unknown(c.loc, "unsupported reconstruction filter '" + c.type +
                                                   "' (supported: box)");
                Properties(c, diagnostics).check_all_used();
            } else {
                diagnostics.unknown(c.loc, "unsupported element " + describe(c) + " in <film>");
            }
        }
        if (!has_filter)
            diagnostics.warn(obj.loc, "no <rfilter> given: Mitsuba would use a Gaussian, gdmlt uses box");
        return film;
    }

    void build_sampler(const ObjectDesc& obj) {
        if (obj.type != "independent")
            diagnostics.unknown(obj.loc, "unsupported sampler '" + obj.type + "' (supported: independent)");
        Properties props(obj, diagnostics);
        const std::int64_t spp = props.get_int("sample_count", 4);
        const std::int64_t seed = props.get_int("seed", 0);
        if (spp < 1) throw InputError(props.loc_of("sample_count"), "sample_count must be positive");
        props.check_all_used();
        sampler.sample_count = static_cast<int>(spp);
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
        if (!(v > 0.f) || !std::isfinite(v)) throw InputError(p->loc, "'" + name + "' must be positive");
        return v;
    }

    BsdfModel build_bsdf_model(const ObjectDesc& obj) {
        Properties props(obj, diagnostics);
        BsdfModel model;
        if (obj.type == "diffuse") {
            model = DiffuseBsdf{props.get_texture("reflectance", Rgb::Constant(0.5f))};
        } else if (obj.type == "dielectric" || obj.type == "thindielectric") {
            const float int_ior = read_ior(props, "int_ior", 1.5046f);
            const float ext_ior = read_ior(props, "ext_ior", 1.000277f);
            const RgbTexture r = props.get_texture("specular_reflectance", Rgb::Ones());
            const RgbTexture t = props.get_texture("specular_transmittance", Rgb::Ones());
            if (obj.type == "dielectric")
                model = DielectricBsdf{int_ior / ext_ior, r, t};
            else
                model = ThinDielectricBsdf{int_ior / ext_ior, r, t};
        } else if (obj.type == "conductor") {
            ConductorBsdf c;
            const std::string material = props.get_string("material", "none");
            if (props.has("eta") || props.has("k")) {
                c.eta = props.get_rgb("eta", Rgb::Zero());
                c.k = props.get_rgb("k", Rgb::Ones());
                c.perfect_mirror = false;
            } else if (material != "none") {
                const auto ior = lookup_conductor(material);
                if (!ior)
                    throw InputError(props.loc_of("material"), "unknown conductor material '" +
                                                                   material + "' (known: none, Ag, Al, Au, Cu, Cr)");
                c.eta = ior->eta;
                c.k = ior->k;
                c.perfect_mirror = false;
            }
            c.specular_reflectance = props.get_texture("specular_reflectance", Rgb::Ones());
            model = c;
        } else {
            diagnostics.unknown(obj.loc, "unknown BSDF '" + obj.type +
                                             "' (supported: diffuse, dielectric, thindielectric, "
                                             "conductor, twosided)");
            model = DiffuseBsdf{};
        }
        props.check_all_used();
        return model;
    }

    Bsdf build_bsdf(const ObjectDesc& obj) {
        if (obj.type != "twosided") {
            if (!obj.children.empty())
                diagnostics.unknown(object(obj.children.front().object).loc,
                                    "unexpected nested element in " + describe(obj));
            return Bsdf(build_bsdf_model(obj));
        }
        Properties(obj, diagnostics).check_all_used();
        std::vector<BsdfModel> nested;
        for (const ChildRef& child : obj.children) {
            const ObjectDesc& c = object(child.object);
            if (c.tag != "bsdf") throw InputError(c.loc, "twosided expects nested <bsdf> elements");
            if (c.type == "twosided") throw InputError(c.loc, "twosided cannot nest twosided");
            nested.push_back(build_bsdf_model(c));
        }
        if (nested.empty() || nested.size() > 2)
            throw InputError(obj.loc, "twosided expects one or two nested BSDFs");
        for (const BsdfModel& m : nested)
            if (std::holds_alternative<DielectricBsdf>(m) || std::holds_alternative<ThinDielectricBsdf>(m))
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
        if (kind == "twosided" && !obj.children.empty()) kind = object(obj.children.front().object).type;
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

    void build_shape(const ObjectDesc& obj) {
        Properties props(obj, diagnostics);
        const Transform world_from_object = props.get_transform("to_world");
        const bool flip_normals = props.get_bool("flip_normals", false);
        std::optional<Shape> shape;

        int bsdf = -1;
        const ObjectDesc* emitter_desc = nullptr;
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
            if (!(radius_object > 0.0)) throw InputError(props.loc_of("radius"), "sphere radius must be positive");
            // A similarity has L^T L = s^2 I; anything else would make an ellipsoid.
            const Eigen::Matrix3d linear = world_from_object.matrix.topLeftCorner<3, 3>();
            const double scale = std::cbrt(std::abs(linear.determinant()));
            const Eigen::Matrix3d gram = linear.transpose() * linear / (scale * scale);
            if (!(scale > 0.0) || (gram - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-5)
                throw InputError(props.loc_of("to_world"),
                                 "sphere to_world must be a similarity (uniform scale, rotation, translation)");
            Sphere s;
            s.center = world_from_object.apply_point(center_object).cast<float>();
            s.radius = static_cast<float>(radius_object * scale);
            s.flip_normals = flip_normals;
            shape.emplace(s, bsdf, obj.id);
        } else {
            TriangleMesh mesh;
            bool face_normals = true;
            if (obj.type == "rectangle") {
                mesh = make_rectangle();
            } else if (obj.type == "cube") {
                mesh = make_cube();
            } else if (obj.type == "disk") {
                mesh = make_disk();
            } else if (obj.type == "obj" || obj.type == "ply" || obj.type == "off") {
                const std::string filename = props.get_string("filename", "");
                if (filename.empty()) throw InputError(obj.loc, describe(obj) + " needs a 'filename'");
                TriangleMeshData data = load_mesh(filename, props.loc_of("filename"));
                face_normals = props.get_bool("face_normals", false);
                props.ignore("flip_tex_coords");
                counts["degenerate_triangles_dropped"] += data.degenerate_triangles_dropped;
                mesh.positions = std::move(data.positions);
                mesh.uvs = std::move(data.uvs);
                mesh.indices = std::move(data.indices);
                if (!face_normals) {
                    mesh.normals = data.normals.empty() ? compute_vertex_normals(TriangleMeshData{
                                                              mesh.positions, {}, {}, mesh.indices, 0})
                                                        : std::move(data.normals);
                }
            } else {
                diagnostics.unknown(obj.loc, "unknown shape '" + obj.type +
                                                 "' (supported: obj, ply, off, rectangle, cube, disk, sphere)");
                return;
            }
            mesh.flip_normals = flip_normals;
            transform_mesh(mesh, world_from_object);
            counts["triangles"] += mesh.triangle_count();
            shape.emplace(std::move(mesh), bsdf, obj.id);
        }
        props.check_all_used();
        features.shape_kinds.insert(obj.type);

        const int shape_index = static_cast<int>(shapes.size());
        if (emitter_desc) {
            if (!(shape->surface_area() > 0.f))
                throw InputError(emitter_desc->loc, "area emitter on a shape of zero area");
            shape->set_emitter(static_cast<int>(emitters.size()));
            build_emitter(*emitter_desc, shape_index);
        }
        shapes.push_back(std::move(*shape));
    }

    void build_emitter(const ObjectDesc& obj, int shape_index) {
        Properties props(obj, diagnostics);
        if (obj.type == "area") {
            if (shape_index < 0) throw InputError(obj.loc, "an area emitter must be nested in a <shape>");
            const Rgb radiance = props.get_rgb("radiance", Rgb::Ones());
            emitters.emplace_back(AreaEmitter{RgbTexture(radiance), shape_index});
            features.has_area_emitters = true;
        } else if (obj.type == "point") {
            PointEmitter p;
            const Transform to_world = props.get_transform("to_world");
            const Vec3d position = props.get_vec3("position", Vec3d::Zero());
            p.position = to_world.apply_point(position).cast<float>();
            p.intensity = props.get_rgb("intensity", Rgb::Ones());
            emitters.emplace_back(p);
            features.has_delta_emitters = true;
        } else if (obj.type == "constant") {
            emitters.emplace_back(ConstantEmitter{props.get_rgb("radiance", Rgb::Ones())});
            features.has_infinite_emitters = true;
        } else {
            diagnostics.unknown(obj.loc, "unknown emitter '" + obj.type +
                                             "' (supported: area, point, constant)");
            return;
        }
        features.emitter_kinds.insert(obj.type);
        props.check_all_used();
        counts["emitters"] += 1;
    }

    void compute_features() {
        std::set<int> used;
        for (const Shape& s : shapes) used.insert(s.bsdf());
        for (int index : used) {
            const Bsdf& b = bsdfs[static_cast<std::size_t>(index)];
            features.bsdf_kinds.insert(bsdf_kind[static_cast<std::size_t>(index)]);
            const RoughnessClass c = b.roughness_class();
            if (c == RoughnessClass::Diffuse) features.has_diffuse = true;
            if (c == RoughnessClass::Glossy) features.has_glossy = true;
            if (b.has_transmission()) features.has_transmission = true;
            if (b.is_delta()) {
                if (b.has_transmission())
                    features.has_delta_transmission = true;
                else
                    features.has_delta_reflection = true;
            }
        }
        features.specular_chains_possible =
            features.has_delta_reflection || features.has_delta_transmission || features.has_glossy;
        counts["shapes"] = shapes.size();
        counts["bsdfs"] = bsdfs.size();
    }
};

}  // namespace

Scene build_scene(const SceneDesc& desc, const BuildOptions& options) {
    Builder b{desc, Diagnostics(options.lenient), {}, {}, {}, {}, {}, {}, false, {}, {}, {}, {}};
    b.build_root();
    b.compute_features();
    if (b.emitters.empty())
        std::cerr << desc.scene_file << ": warning: the scene has no emitters; the image will be black\n";
    return Scene(std::move(b.shapes), std::move(b.bsdfs), std::move(b.emitters), b.camera,
                 std::move(b.integrator), b.sampler, std::move(b.features), std::move(b.counts));
}

}  // namespace gdmlt
