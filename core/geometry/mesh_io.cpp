// SPDX-License-Identifier: GPL-3.0-or-later
// Mesh files -> TriangleMeshData. CGAL reads the polygon soups; triangulation, degeneracy
// filtering and validation are done here so that every format gets the same treatment.
#include "core/geometry/mesh_io.h"

#include <CGAL/IO/OFF.h>
#include <CGAL/IO/PLY.h>
#include <CGAL/Simple_cartesian.h>
#include <tiny_obj_loader.h>
#include <zlib.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <optional>
#include <sstream>
#include <type_traits>
#include <vector>

namespace gdmlt {
namespace {

using Kernel = CGAL::Simple_cartesian<double>;
using CgalPoint = Kernel::Point_3;
using Polygon = std::vector<std::size_t>;
using Triangle = std::array<std::size_t, 3>;

/// What a reader produces before triangulation. Normals and uvs are per vertex and either
/// empty or as many as there are positions.
/// A PLY file's extra per-vertex or per-face values (Mitsuba 3's mesh attributes), `dim` per
/// vertex or face in file order.
struct SoupAttribute {
    std::string name;
    int dim = 1;
    bool per_face = false;
    std::vector<double> values;
};

struct PolygonSoup {
    std::vector<Vec3d> positions;
    std::vector<Vec3d> normals;
    std::vector<Vec2d> uvs;
    std::vector<Polygon> polygons;
    std::vector<SoupAttribute> attributes;
};

/// Any failure while reading: the caller adds the scene location and file name.
struct MeshReadError {
    std::string message;
};

std::vector<Vec3d> to_vectors(const std::vector<CgalPoint>& points) {
    std::vector<Vec3d> vectors;
    vectors.reserve(points.size());
    for (const CgalPoint& p : points) vectors.emplace_back(p.x(), p.y(), p.z());
    return vectors;
}

/// tinyobjloader reads a malformed number ("nan", "1.0.0") as 0 without a word; the lines of
/// vertex data are therefore checked first: every value a number, finite, read whole.
/// The whitespace-separated tokens of one line of an OBJ or OFF file, comments (# to the end)
/// removed: views into the text, no copies (check_obj_numbers runs over every line of a mesh).
std::vector<std::string_view> line_tokens(std::string_view line) {
    if (const std::size_t hash = line.find('#'); hash != std::string_view::npos)
        line = line.substr(0, hash);
    std::vector<std::string_view> tokens;
    std::size_t i = 0;
    while (i < line.size()) {
        while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i])) != 0) ++i;
        const std::size_t start = i;
        while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i])) == 0) ++i;
        if (i > start) tokens.push_back(line.substr(start, i - start));
    }
    return tokens;
}

void check_obj_numbers(const std::string& text) {
    std::size_t line_number = 0;
    for (std::size_t start = 0; start < text.size();) {
        std::size_t end = text.find('\n', start);
        if (end == std::string::npos) end = text.size();
        ++line_number;
        const std::vector<std::string_view> tokens =
            line_tokens(std::string_view(text).substr(start, end - start));
        start = end + 1;
        if (tokens.empty() || (tokens[0] != "v" && tokens[0] != "vt" && tokens[0] != "vn"))
            continue;
        for (std::size_t k = 1; k < tokens.size(); ++k) {
            double value = 0.0;
            const char* first = tokens[k].data();
            const char* last = first + tokens[k].size();
            // A leading '+' is valid OBJ; from_chars does not take it.
            if (first != last && *first == '+') ++first;
            const auto [stop, error] = std::from_chars(first, last, value);
            if (error != std::errc() || stop != last || !std::isfinite(value))
                throw MeshReadError{"line " + std::to_string(line_number) + ": '" +
                                    std::string(tokens[k]) + "' is not a finite number"};
        }
    }
}

PolygonSoup read_obj(std::istream& stream) {
    // tinyobjloader reads the file (CGAL's OBJ reader keeps positions and faces only, and
    // textured scenes need the texture coordinates and normals). As Mitsuba 3's OBJ loader
    // does, a mesh vertex is a distinct (position, texture coordinate, normal) triple of the
    // face corners, so that seams in uv or normals split vertices; vt's v is flipped
    // (u, 1 - v), the image convention of Mitsuba 3 (checked against its loaded mesh); n-gons
    // are triangulated later like every format's. Materials (mtllib, usemtl) are ignored.
    std::ostringstream text;
    text << stream.rdbuf();
    check_obj_numbers(text.str());
    tinyobj::ObjReaderConfig config;
    config.triangulate = false;
    config.vertex_color = false;
    tinyobj::ObjReader reader;
    if (!reader.ParseFromString(text.str(), "", config)) {
        std::string why = reader.Error();
        while (!why.empty() && std::isspace(static_cast<unsigned char>(why.back()))) why.pop_back();
        throw MeshReadError{"not a readable OBJ file" + (why.empty() ? "" : ": " + why)};
    }
    const tinyobj::attrib_t& attrib = reader.GetAttrib();
    const std::size_t n_positions = attrib.vertices.size() / 3;
    const std::size_t n_uvs = attrib.texcoords.size() / 2;
    const std::size_t n_normals = attrib.normals.size() / 3;
    PolygonSoup soup;
    // An attribute that some corners lack is dropped for the whole mesh (the soup's attributes
    // are per vertex, for all vertices or none), and then plays no part in telling vertices
    // apart.
    bool all_uvs = true, all_normals = true;
    for (const tinyobj::shape_t& shape : reader.GetShapes())
        for (const tinyobj::index_t& index : shape.mesh.indices) {
            all_uvs = all_uvs && index.texcoord_index >= 0;
            all_normals = all_normals && index.normal_index >= 0;
        }
    std::map<std::array<int, 3>, std::size_t> vertex_of;
    std::vector<std::array<int, 3>> triples;
    for (const tinyobj::shape_t& shape : reader.GetShapes()) {
        std::size_t corner = 0;
        for (const unsigned face_size : shape.mesh.num_face_vertices) {
            if (corner + face_size > shape.mesh.indices.size())
                throw MeshReadError{"face corners beyond the file's index list"};
            Polygon polygon;
            polygon.reserve(face_size);
            for (unsigned k = 0; k < face_size; ++k, ++corner) {
                const tinyobj::index_t& index = shape.mesh.indices[corner];
                const std::array<int, 3> triple = {index.vertex_index,
                                                   all_uvs ? index.texcoord_index : -1,
                                                   all_normals ? index.normal_index : -1};
                if (triple[0] < 0 || static_cast<std::size_t>(triple[0]) >= n_positions)
                    throw MeshReadError{"a face refers to vertex " +
                                        std::to_string(static_cast<long long>(triple[0]) + 1) +
                                        " but there are " + std::to_string(n_positions)};
                if (triple[1] >= 0 && static_cast<std::size_t>(triple[1]) >= n_uvs)
                    throw MeshReadError{"a face refers to texture coordinate " +
                                        std::to_string(static_cast<long long>(triple[1]) + 1) +
                                        " but there are " + std::to_string(n_uvs)};
                if (triple[2] >= 0 && static_cast<std::size_t>(triple[2]) >= n_normals)
                    throw MeshReadError{"a face refers to normal " +
                                        std::to_string(static_cast<long long>(triple[2]) + 1) +
                                        " but there are " + std::to_string(n_normals)};
                const auto [it, added] = vertex_of.try_emplace(triple, triples.size());
                if (added) triples.push_back(triple);
                polygon.push_back(it->second);
            }
            soup.polygons.push_back(std::move(polygon));
        }
    }
    soup.positions.reserve(triples.size());
    for (const auto& t : triples) {
        const auto i = 3 * static_cast<std::size_t>(t[0]);
        soup.positions.emplace_back(attrib.vertices[i], attrib.vertices[i + 1],
                                    attrib.vertices[i + 2]);
        if (all_uvs) {
            const auto j = 2 * static_cast<std::size_t>(t[1]);
            soup.uvs.emplace_back(attrib.texcoords[j], 1.0 - attrib.texcoords[j + 1]);
        }
        if (all_normals) {
            const auto j = 3 * static_cast<std::size_t>(t[2]);
            soup.normals.emplace_back(attrib.normals[j], attrib.normals[j + 1],
                                      attrib.normals[j + 2]);
        }
    }
    return soup;
}

std::optional<long long> off_integer(std::string_view token) {
    long long value = 0;
    const auto [end, error] = std::from_chars(token.data(), token.data() + token.size(), value);
    if (error != std::errc{} || end != token.data() + token.size()) return std::nullopt;
    return value;
}

/// CGAL's OFF reader trusts the counts it reads: a face of -2^31 vertices ends in
/// vector::_M_default_append, one of 10^11 in an 800 GB allocation. The header's counts and
/// every face's vertex count are checked here first, against the file's size and the vertex
/// count, with the line of the first bad one.
void check_off_counts(const std::string& text) {
    std::vector<std::vector<std::string_view>> lines;  // non-empty lines only
    std::vector<int> line_numbers;
    std::size_t start = 0;
    for (int number = 1; start <= text.size(); ++number) {
        std::size_t end = text.find('\n', start);
        if (end == std::string::npos) end = text.size();
        std::vector<std::string_view> tokens =
            line_tokens(std::string_view(text).substr(start, end - start));
        if (!tokens.empty()) {
            lines.push_back(std::move(tokens));
            line_numbers.push_back(number);
        }
        start = end + 1;
    }
    const auto fail = [&](std::size_t line, const std::string& why) {
        const int number = line < line_numbers.size() ? line_numbers[line] : 0;
        throw MeshReadError{"line " + std::to_string(number) + ": " + why};
    };
    if (lines.empty() || lines[0][0].size() < 3 ||
        lines[0][0].substr(lines[0][0].size() - 3) != "OFF")
        throw MeshReadError{"not an OFF file (no OFF header)"};
    for (const std::string_view token : lines[0])
        if (token == "BINARY") fail(0, "binary OFF files are not supported");
    // The counts follow the header, on its line or the next.
    std::size_t line = lines[0].size() > 1 ? 0 : 1;
    if (line >= lines.size()) fail(line, "missing vertex and face counts");
    const std::vector<std::string_view>& counts = lines[line];
    const std::size_t first = line == 0 ? 1 : 0;
    if (counts.size() < first + 2) fail(line, "expected the vertex and face counts");
    const std::optional<long long> vertices = off_integer(counts[first]);
    const std::optional<long long> faces = off_integer(counts[first + 1]);
    // Every vertex and face takes a line of its own: a count beyond the lines left is a lie.
    const auto lines_left = static_cast<long long>(lines.size() - line - 1);
    if (!vertices || *vertices < 0 || *vertices > lines_left)
        fail(line, "bad vertex count (not an integer in [0, lines in the file])");
    if (!faces || *faces < 0 || *faces > lines_left - *vertices)
        fail(line, "bad face count (not an integer in [0, lines after the vertices])");
    const std::size_t face_start = line + 1 + static_cast<std::size_t>(*vertices);
    for (std::size_t f = 0; f < static_cast<std::size_t>(*faces); ++f) {
        const std::vector<std::string_view>& face = lines[face_start + f];
        const std::optional<long long> n = off_integer(face[0]);
        if (!n || *n < 3 || *n > *vertices || static_cast<long long>(face.size()) < 1 + *n)
            fail(face_start + f,
                 "bad face: its vertex count must be an integer from 3 to the number of "
                 "vertices, followed by that many indices");
    }
}

PolygonSoup read_off(std::istream& stream) {
    const std::string text{std::istreambuf_iterator<char>(stream),
                           std::istreambuf_iterator<char>()};
    check_off_counts(text);
    std::istringstream checked(text);
    std::vector<CgalPoint> points;
    std::vector<Kernel::Vector_3> normals;
    std::vector<Kernel::Point_2> uvs;
    PolygonSoup soup;
    const bool ok = CGAL::IO::read_OFF(
        checked, points, soup.polygons,
        CGAL::parameters::vertex_normal_output_iterator(std::back_inserter(normals))
            .vertex_texture_output_iterator(std::back_inserter(uvs))
            .verbose(false));
    if (!ok)
        throw MeshReadError{
            "not a readable OFF file (malformed or non-finite vertex, or bad face)"};
    soup.positions = to_vectors(points);
    if (normals.size() == points.size())
        for (const Kernel::Vector_3& n : normals) soup.normals.emplace_back(n.x(), n.y(), n.z());
    if (uvs.size() == points.size())
        for (const Kernel::Point_2& uv : uvs) soup.uvs.emplace_back(uv.x(), uv.y());
    return soup;
}

// --- PLY ------------------------------------------------------------------------------------
// CGAL's public read_PLY drops vertex normals and uvs of a polygon soup, so the element loop is
// written here on top of CGAL's PLY header reader and typed property decoders.

using PlyElement = CGAL::IO::internal::PLY_element;

using PlyProperty = CGAL::IO::internal::PLY_read_number;
template <typename Size, typename Index>
using PlyList = CGAL::IO::internal::PLY_read_typed_list_with_typed_size<Size, Index>;

/// Reads a list property into CGAL's own buffer (which assign() reads; it is `mutable`, so
/// writing it through buffer() is well defined). CGAL's get() resizes the buffer to the count
/// it has read before reading any item: a fuzzed count of 10^9 zero-filled 4 GB for 15 s, a
/// negative one threw length_error. Here items are appended one by one and reading stops at the
/// first failure (read_ply_item then reports the truncated file), so memory stays bounded by
/// the file's size.
template <typename Size, typename Index>
void read_bounded_list(std::istream& stream, PlyProperty& property) {
    auto& list = static_cast<PlyList<Size, Index>&>(property);
    auto& items = const_cast<std::vector<Index>&>(list.buffer());
    items.clear();
    const Size count = list.template read<Size>(stream);
    if constexpr (std::is_signed_v<Size>)
        if (count < 0) stream.setstate(std::ios::failbit);
    for (std::size_t i = 0; stream && i < static_cast<std::size_t>(count); ++i)
        items.push_back(list.template read<Index>(stream));
}

/// read_bounded_list for `property` if it is a list (of any of CGAL's size and index types),
/// else null.
using ListReader = void (*)(std::istream&, PlyProperty&);
template <typename Size, typename... Indices>
ListReader list_reader_with_size(PlyProperty& property) {
    ListReader found = nullptr;
    ((found = found ? found
                    : (dynamic_cast<PlyList<Size, Indices>*>(&property) != nullptr
                           ? &read_bounded_list<Size, Indices>
                           : nullptr)),
     ...);
    return found;
}
template <typename... Sizes>
ListReader list_reader_any_size(PlyProperty& property) {
    ListReader found = nullptr;
    ((found =
          found
              ? found
              : list_reader_with_size<Sizes, std::int8_t, std::uint8_t, std::int16_t, std::uint16_t,
                                      std::int32_t, std::uint32_t, float, double>(property)),
     ...);
    return found;
}

/// Per property of `element`: how to read it if it is a list, null for a number (classified
/// once per element, not per item: big meshes have millions of items).
std::vector<ListReader> list_readers(PlyElement& element) {
    std::vector<ListReader> readers;
    for (std::size_t k = 0; k < element.number_of_properties(); ++k)
        readers.push_back(
            list_reader_any_size<std::uint8_t, std::int8_t, std::uint16_t, std::int16_t,
                                 std::uint32_t, std::int32_t>(*element.property(k)));
    return readers;
}

/// Reads one item (all its properties) of a PLY element from the stream.
void read_ply_item(std::istream& stream, PlyElement& element,
                   const std::vector<ListReader>& lists) {
    for (std::size_t k = 0; k < element.number_of_properties(); ++k) {
        if (lists[k])
            lists[k](stream, *element.property(k));
        else
            element.property(k)->get(stream);
        if (stream.fail())
            throw MeshReadError{
                "truncated or malformed PLY data (or a non-finite number in ASCII)"};
    }
}

bool has_real_property(PlyElement& element, const char* name) {
    return element.has_property(name, 0.0);  // float or double
}

double real_property(PlyElement& element, const char* name) {
    double value = 0.0;
    element.assign(value, name);
    return value;
}

/// Face index lists come in several integer types; tries one.
template <typename Index>
bool read_face_indices(PlyElement& element, const char* name, Polygon& polygon) {
    if (!element.has_property(name, std::vector<Index>())) return false;
    std::vector<Index> indices;
    element.assign(indices, name);
    polygon.clear();
    for (Index index : indices) {
        if constexpr (std::is_signed_v<Index>)
            if (index < 0) throw MeshReadError{"negative vertex index in a PLY face"};
        polygon.push_back(static_cast<std::size_t>(index));
    }
    return true;
}

bool read_face_indices_any_type(PlyElement& element, const char* name, Polygon& polygon) {
    return read_face_indices<std::int32_t>(element, name, polygon) ||
           read_face_indices<std::uint32_t>(element, name, polygon) ||
           read_face_indices<std::int16_t>(element, name, polygon) ||
           read_face_indices<std::uint16_t>(element, name, polygon) ||
           read_face_indices<std::int8_t>(element, name, polygon) ||
           read_face_indices<std::uint8_t>(element, name, polygon);
}

/// Which of an element's properties form Mitsuba 3's mesh attributes (src/shapes/ply.h,
/// find_other_fields): r, g, b (or red, green, blue) become `{kind}color`; consecutive
/// `{prefix}_{x|y|z|w}`, `_{r|g|b|a}`, `_{0|1|2|3}` or `_{1|2|3|4}` become `{kind}{prefix}`
/// (`{kind}{prefix}_color` for r, g, b), kept when they have 1 or 3 fields, as Mitsuba keeps
/// them. `kind` is "vertex_" or "face_"; only float and double properties are read.
struct AttributeSpec {
    std::string name;
    std::vector<std::string> properties;
};
std::vector<AttributeSpec> find_attributes(PlyElement& element, const std::string& kind,
                                           const std::vector<std::string>& reserved) {
    std::vector<AttributeSpec> specs;
    std::vector<std::string> skip = reserved;
    for (const auto& names : {std::array<const char*, 3>{"r", "g", "b"},
                              std::array<const char*, 3>{"red", "green", "blue"}}) {
        if (has_real_property(element, names[0]) && has_real_property(element, names[1]) &&
            has_real_property(element, names[2])) {
            specs.push_back({kind + "color", {names[0], names[1], names[2]}});
            break;
        }
    }
    for (const char* name : {"r", "g", "b", "a", "red", "green", "blue", "alpha"})
        skip.emplace_back(name);
    static constexpr std::array<const char*, 4> kCategories = {"xyzw", "rgba", "0123", "1234"};
    std::string prefix;
    int category = -1;
    std::vector<std::string> fields;
    const auto flush = [&] {
        if (fields.size() == 1 || fields.size() == 3)
            specs.push_back({kind + prefix + (category == 1 ? "_color" : ""), fields});
        fields.clear();
        category = -1;
    };
    for (std::size_t k = 0; k < element.number_of_properties(); ++k) {
        const std::string& name = element.property(k)->name();
        const std::size_t underscore = name.rfind('_');
        const bool candidate = std::find(skip.begin(), skip.end(), name) == skip.end() &&
                               underscore != std::string::npos && underscore > 0 &&
                               underscore + 2 == name.size() &&
                               has_real_property(element, name.c_str());
        if (!candidate) {
            flush();
            continue;
        }
        const std::string stem = name.substr(0, underscore);
        const char post = name.back();
        if (!fields.empty() && stem == prefix && fields.size() < 4 &&
            kCategories[static_cast<std::size_t>(category)][fields.size()] == post) {
            fields.push_back(name);
            continue;
        }
        flush();
        for (std::size_t c = 0; c < kCategories.size(); ++c)
            if (kCategories[c][0] == post) {
                prefix = stem;
                category = static_cast<int>(c);
                fields.push_back(name);
                break;
            }
    }
    flush();
    return specs;
}

/// Appends the current item's values of `specs` to the soup's attributes starting at `first`.
void read_attribute_values(PlyElement& element, const std::vector<AttributeSpec>& specs,
                           std::vector<SoupAttribute>& attributes, std::size_t first) {
    for (std::size_t a = 0; a < specs.size(); ++a)
        for (const std::string& property : specs[a].properties)
            attributes[first + a].values.push_back(real_property(element, property.c_str()));
}

std::size_t add_attributes(const std::vector<AttributeSpec>& specs, bool per_face,
                           std::vector<SoupAttribute>& attributes) {
    const std::size_t first = attributes.size();
    for (const AttributeSpec& spec : specs)
        attributes.push_back({spec.name, static_cast<int>(spec.properties.size()), per_face, {}});
    return first;
}

void read_ply_vertices(std::istream& stream, PlyElement& element, PolygonSoup& soup) {
    if (!has_real_property(element, "x") || !has_real_property(element, "y") ||
        !has_real_property(element, "z"))
        throw MeshReadError{"PLY vertices need float or double x, y, z properties"};
    const bool has_normals = has_real_property(element, "nx") && has_real_property(element, "ny") &&
                             has_real_property(element, "nz");
    // Exporters disagree on the uv property names.
    static constexpr std::array<std::array<const char*, 2>, 4> kUvNames = {
        {{"u", "v"}, {"s", "t"}, {"texture_u", "texture_v"}, {"texture_s", "texture_t"}}};
    std::optional<std::array<const char*, 2>> uv_names;
    for (const auto& names : kUvNames)
        if (has_real_property(element, names[0]) && has_real_property(element, names[1])) {
            uv_names = names;
            break;
        }

    std::vector<std::string> reserved = {"x", "y", "z", "nx", "ny", "nz"};
    if (uv_names) reserved.insert(reserved.end(), uv_names->begin(), uv_names->end());
    const std::vector<AttributeSpec> attributes = find_attributes(element, "vertex_", reserved);
    const std::size_t first = add_attributes(attributes, false, soup.attributes);

    const std::vector<ListReader> lists = list_readers(element);
    for (std::size_t i = 0; i < element.number_of_items(); ++i) {
        read_ply_item(stream, element, lists);
        read_attribute_values(element, attributes, soup.attributes, first);
        soup.positions.emplace_back(real_property(element, "x"), real_property(element, "y"),
                                    real_property(element, "z"));
        if (has_normals)
            soup.normals.emplace_back(real_property(element, "nx"), real_property(element, "ny"),
                                      real_property(element, "nz"));
        if (uv_names)
            soup.uvs.emplace_back(real_property(element, (*uv_names)[0]),
                                  real_property(element, (*uv_names)[1]));
    }
}

void read_ply_faces(std::istream& stream, PlyElement& element, PolygonSoup& soup) {
    const std::vector<AttributeSpec> attributes =
        find_attributes(element, "face_", {"vertex_indices", "vertex_index"});
    const std::size_t first = add_attributes(attributes, true, soup.attributes);
    const std::vector<ListReader> lists = list_readers(element);
    for (std::size_t i = 0; i < element.number_of_items(); ++i) {
        read_ply_item(stream, element, lists);
        read_attribute_values(element, attributes, soup.attributes, first);
        Polygon polygon;
        if (!read_face_indices_any_type(element, "vertex_indices", polygon) &&
            !read_face_indices_any_type(element, "vertex_index", polygon))
            throw MeshReadError{"PLY faces need a vertex_indices list property"};
        soup.polygons.push_back(std::move(polygon));
    }
}

/// CGAL's header reader adds each `property` to the last `element` without asking whether there
/// is one: a property line before the first element line crashed it (the loader fuzzer found
/// it, tests/core/test_loader_fuzz.cpp). Checks that order on the header as CGAL reads it (line
/// 1 the signature, line 2 the format, keywords from line 3 to end_header), then rewinds.
void check_ply_property_order(std::istream& stream) {
    std::string line;
    bool element_seen = false;
    for (std::size_t number = 1; std::getline(stream, line); ++number) {
        if (number <= 2) continue;
        std::istringstream words(line);
        std::string keyword;
        words >> keyword;
        if (keyword == "end_header") break;
        if (keyword == "element") element_seen = true;
        if (keyword == "property" && !element_seen)
            throw MeshReadError{"PLY header line " + std::to_string(number) +
                                ": a property before any element"};
    }
    stream.clear();
    stream.seekg(0);
}

PolygonSoup read_ply(std::istream& stream) {
    check_ply_property_order(stream);
    CGAL::IO::internal::PLY_reader reader(/*verbose=*/false);
    if (!reader.init(stream)) throw MeshReadError{"not a PLY file (bad header)"};
    PolygonSoup soup;
    for (std::size_t e = 0; e < reader.number_of_elements(); ++e) {
        PlyElement& element = reader.element(e);
        if (element.name() == "vertex" || element.name() == "vertices") {
            read_ply_vertices(stream, element, soup);
        } else if (element.name() == "face" || element.name() == "faces") {
            read_ply_faces(stream, element, soup);
        } else {
            // Unknown elements still have to be consumed to reach the ones after them. One
            // without properties occupies no bytes however many items it claims (counting to a
            // fuzzed 2^40 items hung the loader).
            if (element.number_of_properties() == 0) continue;
            const std::vector<ListReader> lists = list_readers(element);
            for (std::size_t i = 0; i < element.number_of_items(); ++i)
                read_ply_item(stream, element, lists);
        }
    }
    return soup;
}

// --- Triangulation --------------------------------------------------------------------------

double cross_2d(const Vec2d& a, const Vec2d& b) {
    return a.x() * b.y() - a.y() * b.x();
}

bool point_in_triangle_2d(const Vec2d& p, const Vec2d& a, const Vec2d& b, const Vec2d& c) {
    // Counter-clockwise triangle; points on the boundary count as inside so that an ear never
    // touches another vertex.
    return cross_2d(b - a, p - a) >= 0.0 && cross_2d(c - b, p - b) >= 0.0 &&
           cross_2d(a - c, p - c) >= 0.0;
}

/// Splits one polygon into triangles with the polygon's winding. Ear clipping in the plane of
/// the polygon handles non-convex faces (which a fan would fold over); if no ear is found
/// (self-intersecting or degenerate input) the rest is fanned.
void triangulate_polygon(const std::vector<Vec3d>& positions, const Polygon& polygon,
                         std::vector<Triangle>& triangles) {
    const std::size_t n = polygon.size();
    if (n == 3) {
        triangles.push_back({polygon[0], polygon[1], polygon[2]});
        return;
    }
    // Newell's normal: robust for non-planar and non-convex polygons.
    Vec3d normal = Vec3d::Zero();
    for (std::size_t i = 0; i < n; ++i)
        normal += positions[polygon[i]].cross(positions[polygon[(i + 1) % n]]);
    int drop_axis = 0;
    normal.cwiseAbs().maxCoeff(&drop_axis);
    const int u_axis = (drop_axis + 1) % 3;
    const int v_axis = (drop_axis + 2) % 3;
    // Projecting along the dominant axis keeps the winding when that component is positive.
    const double flip = normal[drop_axis] < 0.0 ? -1.0 : 1.0;
    std::vector<Vec2d> projected;
    projected.reserve(n);
    for (std::size_t index : polygon) {
        const Vec3d& p = positions[index];
        projected.emplace_back(p[u_axis], flip * p[v_axis]);
    }

    std::vector<std::size_t> remaining(n);  // positions in `polygon`
    for (std::size_t i = 0; i < n; ++i) remaining[i] = i;
    while (remaining.size() > 3) {
        const std::size_t count = remaining.size();
        bool clipped = false;
        for (std::size_t i = 0; i < count && !clipped; ++i) {
            const std::size_t previous = remaining[(i + count - 1) % count];
            const std::size_t current = remaining[i];
            const std::size_t next = remaining[(i + 1) % count];
            const Vec2d& a = projected[previous];
            const Vec2d& b = projected[current];
            const Vec2d& c = projected[next];
            if (cross_2d(b - a, c - a) <= 0.0) continue;  // reflex or flat corner
            bool contains_other = false;
            for (std::size_t other : remaining) {
                if (other == previous || other == current || other == next) continue;
                if (point_in_triangle_2d(projected[other], a, b, c)) {
                    contains_other = true;
                    break;
                }
            }
            if (contains_other) continue;
            triangles.push_back({polygon[previous], polygon[current], polygon[next]});
            remaining.erase(remaining.begin() + static_cast<std::ptrdiff_t>(i));
            clipped = true;
        }
        if (!clipped) break;
    }
    for (std::size_t i = 1; i + 1 < remaining.size(); ++i)
        triangles.push_back(
            {polygon[remaining[0]], polygon[remaining[i]], polygon[remaining[i + 1]]});
}

/// A triangle whose height is below float resolution of its longest edge cannot be
/// intersected or shaded meaningfully.
bool is_degenerate(const Triangle& t, const std::vector<Vec3f>& positions) {
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) return true;
    const Vec3d a = positions[t[0]].cast<double>();
    const Vec3d b = positions[t[1]].cast<double>();
    const Vec3d c = positions[t[2]].cast<double>();
    const double twice_area = (b - a).cross(c - a).norm();
    const double longest_edge_squared =
        std::max({(b - a).squaredNorm(), (c - b).squaredNorm(), (a - c).squaredNorm()});
    constexpr double kMinHeightOverEdge = 1e-7;
    return !(twice_area > kMinHeightOverEdge * longest_edge_squared);
}

/// Mitsuba's .serialized meshes, format versions 3 and 4 (Mitsuba 0.5-3; the published scenes'
/// files): per mesh an uncompressed header (uint16 0x041C, uint16 version) and a zlib stream of
/// a uint32 flag word (0x0001 normals, 0x0002 texture coordinates, 0x0008 colours, 0x0010 face
/// normals, 0x2000 double precision), the name (version 4: zero-terminated), uint64 vertex and
/// triangle counts, the vertex arrays and the triangles' indices (uint32, or uint64 beyond 2^32
/// vertices); the file ends with each mesh's offset (uint64; version 3: uint32) and the mesh
/// count (uint32). All little-endian.
PolygonSoup read_serialized(std::istream& in, int shape_index, bool& face_normals) {
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const auto read_le = [](const unsigned char* p, int size) {
        std::uint64_t v = 0;
        for (int i = size - 1; i >= 0; --i) v = (v << 8) | p[i];
        return v;
    };
    const auto* data = reinterpret_cast<const unsigned char*>(bytes.data());
    const std::size_t size = bytes.size();
    if (size < 8) throw MeshReadError{"too short for a serialized mesh"};
    if (read_le(data, 2) != 0x041C) throw MeshReadError{"not a serialized mesh (no 0x041C mark)"};
    const auto version = static_cast<int>(read_le(data + 2, 2));
    if (version != 3 && version != 4)
        throw MeshReadError{"serialized format version " + std::to_string(version) +
                            " is not supported (3 and 4 are)"};
    const std::uint64_t count = read_le(data + size - 4, 4);
    const std::size_t entry = version == 4 ? 8 : 4;
    if (count == 0 || count > (size - 4) / entry)
        throw MeshReadError{"its table of meshes is damaged"};
    if (shape_index < 0 || static_cast<std::uint64_t>(shape_index) >= count)
        throw MeshReadError{"shape_index " + std::to_string(shape_index) + " but the file holds " +
                            std::to_string(count) + " mesh(es)"};
    const std::size_t table = size - 4 - entry * count;
    const std::uint64_t offset = read_le(
        data + table + entry * static_cast<std::size_t>(shape_index), static_cast<int>(entry));
    if (offset + 4 > table || read_le(data + offset, 2) != 0x041C ||
        read_le(data + offset + 2, 2) != static_cast<std::uint64_t>(version))
        throw MeshReadError{"mesh " + std::to_string(shape_index) + " has no header at its offset"};

    // Inflate the mesh's stream (it ends where zlib says; the next header follows).
    std::vector<unsigned char> raw;
    z_stream z{};
    if (inflateInit(&z) != Z_OK) throw MeshReadError{"zlib failed to start"};
    z.next_in = const_cast<unsigned char*>(data + offset + 4);
    z.avail_in = static_cast<uInt>(std::min<std::uint64_t>(table - offset - 4, 0xFFFFFFFFu));
    int status = Z_OK;
    while (status == Z_OK) {
        const std::size_t done = raw.size();
        raw.resize(done + (std::size_t{1} << 20));
        z.next_out = raw.data() + done;
        z.avail_out = 1u << 20;
        status = inflate(&z, Z_NO_FLUSH);
        raw.resize(done + (std::size_t{1} << 20) - z.avail_out);
    }
    inflateEnd(&z);
    if (status != Z_STREAM_END)
        throw MeshReadError{"its compressed data is damaged (zlib status " +
                            std::to_string(status) + ")"};

    std::size_t at = 0;
    const auto take = [&](std::size_t bytes_wanted) {
        if (bytes_wanted > raw.size() - at) throw MeshReadError{"its mesh data ends early"};
        const unsigned char* p = raw.data() + at;
        at += bytes_wanted;
        return p;
    };
    const auto flags = static_cast<std::uint32_t>(read_le(take(4), 4));
    if (version == 4)
        while (*take(1) != 0) {
        }
    const std::uint64_t vertices = read_le(take(8), 8);
    const std::uint64_t triangles = read_le(take(8), 8);
    const bool doubles = (flags & 0x2000u) != 0;
    const std::size_t real = doubles ? 8 : 4;
    // Counts are checked against what is left before anything is allocated.
    const std::size_t left = raw.size() - at;
    if (vertices == 0 || triangles == 0 || vertices > left / (3 * real) || triangles > left / 12)
        throw MeshReadError{"its vertex or triangle count does not fit its data"};
    const auto read_real = [&](const unsigned char* p) {
        if (doubles) {
            const std::uint64_t b = read_le(p, 8);
            double d = 0.0;
            std::memcpy(&d, &b, 8);
            return d;
        }
        const auto b = static_cast<std::uint32_t>(read_le(p, 4));
        float f = 0.f;
        std::memcpy(&f, &b, 4);
        return static_cast<double>(f);
    };
    PolygonSoup soup;
    const auto n = static_cast<std::size_t>(vertices);
    soup.positions.resize(n);
    for (Vec3d& p : soup.positions) {
        const unsigned char* q = take(3 * real);
        p = Vec3d(read_real(q), read_real(q + real), read_real(q + 2 * real));
    }
    if (flags & 0x0001u) {
        soup.normals.resize(n);
        for (Vec3d& v : soup.normals) {
            const unsigned char* q = take(3 * real);
            v = Vec3d(read_real(q), read_real(q + real), read_real(q + 2 * real));
        }
    }
    if (flags & 0x0002u) {
        soup.uvs.resize(n);
        for (Vec2d& uv : soup.uvs) {
            const unsigned char* q = take(2 * real);
            uv = Vec2d(read_real(q), read_real(q + real));
        }
    }
    if (flags & 0x0008u) take(n * 3 * real);  // vertex colours: not used
    const std::size_t index_size = vertices > 0xFFFFFFFFull ? 8 : 4;
    soup.polygons.resize(static_cast<std::size_t>(triangles));
    for (Polygon& polygon : soup.polygons) {
        const unsigned char* q = take(3 * index_size);
        polygon = {
            static_cast<std::size_t>(read_le(q, static_cast<int>(index_size))),
            static_cast<std::size_t>(read_le(q + index_size, static_cast<int>(index_size))),
            static_cast<std::size_t>(read_le(q + 2 * index_size, static_cast<int>(index_size)))};
    }
    face_normals = (flags & 0x0010u) != 0;
    return soup;
}

std::string lowercase_extension(const std::string& path) {
    std::string extension = std::filesystem::path(path).extension().string();
    std::transform(extension.begin(), extension.end(), extension.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return extension;
}

std::string vector_text(const Vec3d& v) {
    return "(" + std::to_string(v.x()) + ", " + std::to_string(v.y()) + ", " +
           std::to_string(v.z()) + ")";
}

}  // namespace

TriangleMeshData load_mesh(const std::string& path, const FileLoc& loc, int shape_index) {
    const auto fail = [&](const std::string& message) -> InputError {
        return InputError(loc, "mesh file '" + path + "': " + message);
    };

    const std::string extension = lowercase_extension(path);
    if (extension != ".obj" && extension != ".ply" && extension != ".off" &&
        extension != ".serialized")
        throw fail("unsupported format '" + extension +
                   "' (expected .obj, .ply, .off or .serialized)");
    if (const std::string problem = input_file_problem(path); !problem.empty()) throw fail(problem);
    // Binary mode: PLY (and OFF) may be binary; text readers do not mind.
    std::ifstream stream(path, std::ios::binary);
    if (!stream) throw fail("cannot open file");

    PolygonSoup soup;
    bool face_normals = false;
    try {
        if (extension == ".serialized")
            soup = read_serialized(stream, shape_index, face_normals);
        else if (extension == ".obj")
            soup = read_obj(stream);
        else if (extension == ".ply")
            soup = read_ply(stream);
        else
            soup = read_off(stream);
    } catch (const MeshReadError& read_error) {
        throw fail(read_error.message);
    }

    const std::size_t vertex_count = soup.positions.size();
    if (vertex_count >= std::numeric_limits<std::uint32_t>::max())
        throw fail("too many vertices for 32-bit indices");

    TriangleMeshData mesh;
    mesh.face_normals = face_normals;
    mesh.positions.reserve(vertex_count);
    for (std::size_t i = 0; i < vertex_count; ++i) {
        const Vec3f p = soup.positions[i].cast<float>();
        // Checked after the float conversion: a huge double becomes an infinite float.
        if (!p.allFinite())
            throw fail("vertex " + std::to_string(i) + " has a non-finite position " +
                       vector_text(soup.positions[i]));
        mesh.positions.push_back(p);
    }

    // File normals and uvs are optional extras: if any is unusable, drop that attribute for
    // the whole mesh (the builder then computes smooth normals) rather than reject the mesh.
    if (soup.normals.size() == vertex_count) {
        mesh.normals.reserve(vertex_count);
        for (const Vec3d& n : soup.normals) {
            const Vec3f unit = n.normalized().cast<float>();
            if (!(n.norm() > 0.0) || !unit.allFinite()) {
                mesh.normals.clear();
                break;
            }
            mesh.normals.push_back(unit);
        }
    }
    if (soup.uvs.size() == vertex_count) {
        mesh.uvs.reserve(vertex_count);
        for (const Vec2d& uv : soup.uvs) {
            const Vec2f uv_float = uv.cast<float>();
            if (!uv_float.allFinite()) {
                mesh.uvs.clear();
                break;
            }
            mesh.uvs.push_back(uv_float);
        }
    }

    std::vector<Triangle> triangles;
    std::vector<std::size_t> triangle_faces;  // the polygon each triangle came from
    for (std::size_t f = 0; f < soup.polygons.size(); ++f) {
        const Polygon& polygon = soup.polygons[f];
        for (std::size_t index : polygon)
            if (index >= vertex_count)
                throw fail("face " + std::to_string(f) + " refers to vertex " +
                           std::to_string(index) + " but there are only " +
                           std::to_string(vertex_count));
        if (polygon.size() < 3) {
            ++mesh.degenerate_triangles_dropped;
            continue;
        }
        triangulate_polygon(soup.positions, polygon, triangles);
        triangle_faces.resize(triangles.size(), f);
    }

    // Attributes with a value per vertex or face of the file, stored per kept triangle.
    std::vector<const SoupAttribute*> attributes;
    for (const SoupAttribute& a : soup.attributes) {
        const std::size_t count = a.per_face ? soup.polygons.size() : vertex_count;
        if (a.values.size() != count * static_cast<std::size_t>(a.dim)) continue;
        attributes.push_back(&a);
        mesh.attributes.push_back({a.name, a.dim, a.per_face, {}});
    }
    mesh.indices.reserve(3 * triangles.size());
    for (std::size_t i = 0; i < triangles.size(); ++i) {
        const Triangle& t = triangles[i];
        if (is_degenerate(t, mesh.positions)) {
            ++mesh.degenerate_triangles_dropped;
            continue;
        }
        for (std::size_t index : t) mesh.indices.push_back(static_cast<std::uint32_t>(index));
        for (std::size_t a = 0; a < attributes.size(); ++a) {
            const SoupAttribute& from = *attributes[a];
            const auto dim = static_cast<std::size_t>(from.dim);
            std::vector<float>& to = mesh.attributes[a].values;
            if (from.per_face) {
                for (std::size_t c = 0; c < dim; ++c)
                    to.push_back(static_cast<float>(from.values[triangle_faces[i] * dim + c]));
            } else {
                for (std::size_t index : t)
                    for (std::size_t c = 0; c < dim; ++c)
                        to.push_back(static_cast<float>(from.values[index * dim + c]));
            }
        }
    }
    if (mesh.indices.empty()) throw fail("no (non-degenerate) triangles");
    for (const MeshAttribute& a : mesh.attributes)
        for (const float v : a.values)
            if (!std::isfinite(v)) throw fail("attribute '" + a.name + "' has a non-finite value");
    return mesh;
}

std::vector<Vec3f> compute_vertex_normals(const TriangleMeshData& mesh) {
    // Each triangle contributes its unit normal weighted by its corner angle at the vertex:
    // unlike area weighting, the result does not depend on how a surface is tessellated.
    std::vector<Vec3d> sums(mesh.positions.size(), Vec3d::Zero());
    std::vector<Vec3d> any_face_normal(mesh.positions.size(), Vec3d::Zero());
    for (std::size_t t = 0; t + 2 < mesh.indices.size(); t += 3) {
        const std::array<std::uint32_t, 3> corner = {mesh.indices[t], mesh.indices[t + 1],
                                                     mesh.indices[t + 2]};
        const std::array<Vec3d, 3> p = {mesh.positions[corner[0]].cast<double>(),
                                        mesh.positions[corner[1]].cast<double>(),
                                        mesh.positions[corner[2]].cast<double>()};
        const Vec3d face_cross = (p[1] - p[0]).cross(p[2] - p[0]);
        const double face_cross_norm = face_cross.norm();
        if (!(face_cross_norm > 0.0)) continue;
        const Vec3d face_normal = face_cross / face_cross_norm;
        for (int k = 0; k < 3; ++k) {
            const Vec3d to_next =
                p[static_cast<std::size_t>((k + 1) % 3)] - p[static_cast<std::size_t>(k)];
            const Vec3d to_previous =
                p[static_cast<std::size_t>((k + 2) % 3)] - p[static_cast<std::size_t>(k)];
            // atan2 of |cross| and dot is accurate for small and near-straight angles alike.
            const double angle =
                std::atan2(to_next.cross(to_previous).norm(), to_next.dot(to_previous));
            sums[corner[static_cast<std::size_t>(k)]] += angle * face_normal;
            any_face_normal[corner[static_cast<std::size_t>(k)]] = face_normal;
        }
    }

    std::vector<Vec3f> normals;
    normals.reserve(sums.size());
    for (std::size_t i = 0; i < sums.size(); ++i) {
        const double length = sums[i].norm();
        if (length > 1e-12) {
            normals.push_back((sums[i] / length).cast<float>());
        } else if (any_face_normal[i].squaredNorm() > 0.0) {
            // Opposite faces cancelled (e.g. a doubled sheet): any adjacent face will do.
            normals.push_back(any_face_normal[i].cast<float>());
        } else {
            // Unreferenced vertex: never shaded, but the result must still be unit length.
            normals.push_back(Vec3f::UnitZ());
        }
    }
    return normals;
}

}  // namespace gdmlt
