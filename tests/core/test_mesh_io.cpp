// SPDX-License-Identifier: GPL-3.0-or-later
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>
#include <string>
#include <tuple>
#include <vector>

#include "core/geometry/mesh_io.h"

namespace gdmlt {
namespace {

namespace fs = std::filesystem;

const FileLoc kSceneLoc{"scene.xml", 7, 3};

/// A fresh directory per test, removed afterwards.
class TempDir {
  public:
    TempDir() {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        path_ = fs::temp_directory_path() /
                ("gdmlt_mesh_io_" + std::to_string(::getpid()) + "_" + info->name());
        fs::remove_all(path_);
        fs::create_directories(path_);
    }
    ~TempDir() {
        std::error_code ignored;
        fs::remove_all(path_, ignored);
    }
    TempDir(const TempDir&) = delete;
    TempDir& operator=(const TempDir&) = delete;

    const fs::path& path() const { return path_; }

    std::string write(const std::string& name, const std::string& contents) const {
        const fs::path file = path_ / name;
        std::ofstream(file, std::ios::binary) << contents;
        return file.string();
    }

  private:
    fs::path path_;
};

Vec3d triangle_cross(const TriangleMeshData& mesh, std::size_t t) {
    const Vec3d a = mesh.positions[mesh.indices[3 * t]].cast<double>();
    const Vec3d b = mesh.positions[mesh.indices[3 * t + 1]].cast<double>();
    const Vec3d c = mesh.positions[mesh.indices[3 * t + 2]].cast<double>();
    return (b - a).cross(c - a);
}

double total_area(const TriangleMeshData& mesh) {
    double area = 0.0;
    for (std::size_t t = 0; t < mesh.triangle_count(); ++t)
        area += 0.5 * triangle_cross(mesh, t).norm();
    return area;
}

/// Expects load_mesh to throw an InputError naming the scene location and the mesh file;
/// returns the message.
std::string load_error(const std::string& path) {
    try {
        load_mesh(path, kSceneLoc);
    } catch (const InputError& error) {
        const std::string message = error.what();
        EXPECT_EQ(message.rfind("scene.xml:7:3:", 0), 0u) << message;
        EXPECT_NE(message.find(path), std::string::npos) << message;
        return message;
    }
    ADD_FAILURE() << "no InputError for " << path;
    return {};
}

/// One mesh of a Mitsuba .serialized file (format 3 or 4) as load_mesh expects it.
struct SerializedMesh {
    std::vector<Vec3d> positions;
    std::vector<Vec3d> normals;  // empty: none
    std::vector<Vec2d> uvs;      // empty: none
    std::vector<std::uint32_t> indices;
    bool doubles = false;
    bool face_normals = false;
};

template <typename T>
void put(std::string& out, T value) {
    char bytes[sizeof(T)];
    std::memcpy(bytes, &value, sizeof(T));  // this machine is little-endian, as the format
    out.append(bytes, sizeof(T));
}

/// The file's bytes: per mesh the 0x041C mark, the version and a zlib stream; then the table of
/// offsets (uint64 in version 4, uint32 in 3) and the mesh count.
std::string serialized_file(const std::vector<SerializedMesh>& meshes, std::uint16_t version) {
    std::string file;
    std::vector<std::uint64_t> offsets;
    for (const SerializedMesh& m : meshes) {
        offsets.push_back(file.size());
        put<std::uint16_t>(file, 0x041C);
        put<std::uint16_t>(file, version);
        std::string body;
        std::uint32_t flags = m.doubles ? 0x2000u : 0x1000u;
        if (!m.normals.empty()) flags |= 0x0001u;
        if (!m.uvs.empty()) flags |= 0x0002u;
        if (m.face_normals) flags |= 0x0010u;
        put(body, flags);
        if (version == 4) body += std::string("mesh") + '\0';
        put<std::uint64_t>(body, m.positions.size());
        put<std::uint64_t>(body, m.indices.size() / 3);
        const auto real = [&](double v) {
            if (m.doubles)
                put(body, v);
            else
                put(body, static_cast<float>(v));
        };
        for (const Vec3d& p : m.positions) real(p.x()), real(p.y()), real(p.z());
        for (const Vec3d& n : m.normals) real(n.x()), real(n.y()), real(n.z());
        for (const Vec2d& uv : m.uvs) real(uv.x()), real(uv.y());
        for (std::uint32_t i : m.indices) put(body, i);
        uLongf size = compressBound(static_cast<uLong>(body.size()));
        std::string packed(size, '\0');
        EXPECT_EQ(compress2(reinterpret_cast<Bytef*>(packed.data()), &size,
                            reinterpret_cast<const Bytef*>(body.data()),
                            static_cast<uLong>(body.size()), 6),
                  Z_OK);
        file.append(packed.data(), size);
    }
    for (std::uint64_t offset : offsets) {
        if (version == 4)
            put(file, offset);
        else
            put(file, static_cast<std::uint32_t>(offset));
    }
    put(file, static_cast<std::uint32_t>(meshes.size()));
    return file;
}

TEST(MeshIo, LoadsTheMeshesOfMitsubasSerializedFiles) {
    // Mitsuba's scenes (its matpreview object, 37 of the scenes in its data repository) keep
    // their meshes in .serialized files. Two meshes per file, versions 3 and 4, single and
    // double precision, with and without normals and uvs; shape_index picks one.
    const TempDir dir;
    SerializedMesh quad;
    quad.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
    quad.normals = {{0, 0, 1}, {0, 0, 1}, {0, 0, 1}, {0, 0, 1}};
    quad.uvs = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
    quad.indices = {0, 1, 2, 0, 2, 3};
    SerializedMesh triangle;
    triangle.positions = {{0, 0, 1}, {0.1, 0, 1}, {0, 0.3, 1}};
    triangle.indices = {0, 1, 2};
    triangle.doubles = true;
    triangle.face_normals = true;
    for (const std::uint16_t version : {std::uint16_t{3}, std::uint16_t{4}}) {
        const std::string path = dir.write("two_" + std::to_string(version) + ".serialized",
                                           serialized_file({quad, triangle}, version));
        const TriangleMeshData first = load_mesh(path, kSceneLoc, 0);
        ASSERT_EQ(first.positions.size(), 4u);
        EXPECT_EQ(first.indices, quad.indices);
        EXPECT_EQ(first.positions[2], Vec3f(1, 1, 0));
        ASSERT_EQ(first.normals.size(), 4u);
        EXPECT_EQ(first.normals[3], Vec3f(0, 0, 1));
        ASSERT_EQ(first.uvs.size(), 4u);
        EXPECT_EQ(first.uvs[1], Vec2f(1, 0));
        EXPECT_FALSE(first.face_normals);
        const TriangleMeshData second = load_mesh(path, kSceneLoc, 1);
        ASSERT_EQ(second.positions.size(), 3u);
        EXPECT_EQ(second.positions[2], Vec3f(0.f, 0.3f, 1.f));
        EXPECT_TRUE(second.normals.empty());
        EXPECT_TRUE(second.uvs.empty());
        EXPECT_TRUE(second.face_normals);
        try {
            load_mesh(path, kSceneLoc, 2);
            ADD_FAILURE() << "shape_index 2 of 2 meshes loaded";
        } catch (const InputError& e) {
            EXPECT_NE(std::string(e.what()).find("holds 2"), std::string::npos) << e.what();
        }
    }
}

TEST(MeshIo, DamagedSerializedFilesAreInputErrors) {
    const TempDir dir;
    SerializedMesh triangle;
    triangle.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    triangle.indices = {0, 1, 2};
    const std::string good = serialized_file({triangle}, 4);
    std::string wrong_mark = good;
    wrong_mark[0] = 'x';
    std::string version_5 = good;
    version_5[2] = 5;
    std::string truncated = good.substr(0, 12) + good.substr(good.size() - 12);
    for (const auto& [name, bytes, words] :
         std::vector<std::tuple<std::string, std::string, std::string>>{
             {"mark", wrong_mark, "0x041C"},
             {"version", version_5, "version 5"},
             {"truncated", truncated, "compressed"},
             {"empty", std::string(), "too short"}}) {
        const std::string message = load_error(dir.write(name + ".serialized", bytes));
        EXPECT_NE(message.find(words), std::string::npos) << name << ": " << message;
    }
    // A vertex index beyond the vertices.
    triangle.indices = {0, 1, 7};
    const std::string message =
        load_error(dir.write("index.serialized", serialized_file({triangle}, 3)));
    EXPECT_NE(message.find("vertex 7"), std::string::npos) << message;
}

TEST(MeshIo, LoadsObjTriangles) {
    const TempDir dir;
    const std::string path = dir.write("tris.obj",
                                       "# two triangles\n"
                                       "v 0 0 0 # a comment after the numbers\n"
                                       "v 1 0 0\nv 0 1 0\nv 1 1 0\n"
                                       "vn 0 0 1\nvt 0 0\n"
                                       "f 1/1/1 2/1/1 3/1/1\n"
                                       "f 2 4 3\n");
    const TriangleMeshData mesh = load_mesh(path, kSceneLoc);
    EXPECT_EQ(mesh.positions.size(), 4u);
    EXPECT_EQ(mesh.triangle_count(), 2u);
    EXPECT_EQ(mesh.degenerate_triangles_dropped, 0u);
    EXPECT_EQ(mesh.indices, (std::vector<std::uint32_t>{0, 1, 2, 1, 3, 2}));
}

TEST(MeshIo, ObjKeepsTextureCoordinatesAndNormalsAsMitsubaDoes) {
    // Mitsuba 3's OBJ loader (probed with this file in 3.9.1): a vertex per distinct
    // (position, vt, vn) of the face corners, texture coordinates (u, 1 - v), the file's
    // normals. Here position 1 is used with two normals, so it becomes two vertices; the quad
    // is two triangles.
    const TempDir dir;
    const std::string path = dir.write("quad.obj",
                                       "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
                                       "vt 0.1 0.2\nvt 0.9 0.2\nvt 0.9 0.7\nvt 0.1 0.7\n"
                                       "vn 0 0 1\nvn 0 0.6 0.8\n"
                                       "f 1/1/1 2/2/1 3/3/2 4/4/2\n"
                                       "f 1/1/1 3/3/2 4/4/1\n");
    const TriangleMeshData mesh = load_mesh(path, kSceneLoc);
    ASSERT_EQ(mesh.positions.size(), 5u);
    ASSERT_EQ(mesh.uvs.size(), 5u);
    ASSERT_EQ(mesh.normals.size(), 5u);
    EXPECT_EQ(mesh.triangle_count(), 3u);
    const std::vector<std::array<float, 8>> want = {// position, uv, normal
                                                    {0, 0, 0, 0.1f, 0.8f, 0, 0, 1},
                                                    {1, 0, 0, 0.9f, 0.8f, 0, 0, 1},
                                                    {1, 1, 0, 0.9f, 0.3f, 0, 0.6f, 0.8f},
                                                    {0, 1, 0, 0.1f, 0.3f, 0, 0.6f, 0.8f},
                                                    {0, 1, 0, 0.1f, 0.3f, 0, 0, 1}};
    for (const auto& w : want) {
        bool found = false;
        for (std::size_t i = 0; i < mesh.positions.size() && !found; ++i)
            found = (mesh.positions[i] - Vec3f(w[0], w[1], w[2])).norm() < 1e-6f &&
                    (mesh.uvs[i] - Vec2f(w[3], w[4])).norm() < 1e-6f &&
                    (mesh.normals[i] - Vec3f(w[5], w[6], w[7])).norm() < 1e-6f;
        EXPECT_TRUE(found) << w[0] << " " << w[1] << " " << w[2] << " uv " << w[3] << " " << w[4];
    }
}

TEST(MeshIo, ObjFaceIndexBeyondTheFileIsAnInputError) {
    const TempDir dir;
    load_error(dir.write("vt.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/2 3/1\n"));
    load_error(dir.write("v.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n"));
    load_error(dir.write("word.obj", "v 0 0 0\nv 1 0 zero\nv 0 1 0\nf 1 2 3\n"));
}

TEST(MeshIo, TriangulatesAQuadKeepingItsWinding) {
    const TempDir dir;
    const std::string path =
        dir.write("quad.obj", "v 0 0 0\nv 2 0 0\nv 2 1 0\nv 0 1 0\nf 1 2 3 4\n");
    const TriangleMeshData mesh = load_mesh(path, kSceneLoc);
    ASSERT_EQ(mesh.triangle_count(), 2u);
    EXPECT_NEAR(total_area(mesh), 2.0, 1e-6);
    for (std::size_t t = 0; t < 2; ++t) EXPECT_GT(triangle_cross(mesh, t).z(), 0.0);
}

TEST(MeshIo, TriangulatesANonConvexPolygonWithoutFolding) {
    // An L shape listed from a vertex whose fan would cover the notch: the triangles must all
    // face +z and add up to the polygon's area (3).
    const TempDir dir;
    const std::string path = dir.write("ell.off",
                                       "OFF\n6 1 0\n"
                                       "2 0 0\n2 1 0\n1 1 0\n1 2 0\n0 2 0\n0 0 0\n"
                                       "6 0 1 2 3 4 5\n");
    const TriangleMeshData mesh = load_mesh(path, kSceneLoc);
    ASSERT_EQ(mesh.triangle_count(), 4u);
    EXPECT_NEAR(total_area(mesh), 3.0, 1e-6);
    for (std::size_t t = 0; t < 4; ++t) EXPECT_GT(triangle_cross(mesh, t).z(), 0.0) << t;
}

TEST(MeshIo, LoadsOffTriangles) {
    const TempDir dir;
    const std::string path = dir.write(
        "tet.off", "OFF\n4 4 6\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n");
    const TriangleMeshData mesh = load_mesh(path, kSceneLoc);
    EXPECT_EQ(mesh.triangle_count(), 4u);
    EXPECT_TRUE(mesh.normals.empty());
}

TEST(MeshIo, KeepsPlyVertexNormalsAndUvs) {
    const TempDir dir;
    const std::string path = dir.write("uv.ply",
                                       "ply\nformat ascii 1.0\n"
                                       "element vertex 3\n"
                                       "property float x\nproperty float y\nproperty float z\n"
                                       "property float nx\nproperty float ny\nproperty float nz\n"
                                       "property float u\nproperty float v\n"
                                       "element face 1\n"
                                       "property list uchar int vertex_indices\n"
                                       "end_header\n"
                                       "0 0 0 0 0 2 0 0\n"
                                       "1 0 0 0 0 1 1 0\n"
                                       "0 1 0 0 0 1 0 1\n"
                                       "3 0 1 2\n");
    const TriangleMeshData mesh = load_mesh(path, kSceneLoc);
    ASSERT_EQ(mesh.triangle_count(), 1u);
    ASSERT_EQ(mesh.normals.size(), 3u);
    EXPECT_EQ(mesh.normals[0], Vec3f(0, 0, 1));  // normalised on load
    ASSERT_EQ(mesh.uvs.size(), 3u);
    EXPECT_EQ(mesh.uvs[1], Vec2f(1, 0));
    EXPECT_EQ(mesh.uvs[2], Vec2f(0, 1));
}

/// The attribute called `name` of `mesh`, or null.
const MeshAttribute* find_attribute(const TriangleMeshData& mesh, const std::string& name) {
    for (const MeshAttribute& a : mesh.attributes)
        if (a.name == name) return &a;
    return nullptr;
}

TEST(MeshIo, PlyVertexAndFaceAttributesAreGroupedAsMitsubaGroupsThem) {
    // Mitsuba 3's naming (src/shapes/ply.h): r, g, b -> vertex_color; color_0..2 ->
    // face_color; weight_0 -> face_weight (one field); a pair (two fields) and an unknown
    // single property are not attributes. A quad and a triangle: the quad's two triangles both
    // carry its face values, and vertex values are stored per triangle corner.
    const TempDir dir;
    const std::string path =
        dir.write("attributes.ply",
                  "ply\nformat ascii 1.0\n"
                  "element vertex 5\n"
                  "property float x\nproperty float y\nproperty float z\n"
                  "property float r\nproperty float g\nproperty float b\n"
                  "property float pair_0\nproperty float pair_1\nproperty float lonely\n"
                  "element face 2\n"
                  "property list uchar int vertex_indices\n"
                  "property float color_0\nproperty float color_1\nproperty float color_2\n"
                  "property float weight_0\n"
                  "end_header\n"
                  "0 0 0 0.1 0.2 0.3 9 9 9\n"
                  "1 0 0 0.4 0.5 0.6 9 9 9\n"
                  "1 1 0 0.7 0.8 0.9 9 9 9\n"
                  "0 1 0 1.0 1.1 1.2 9 9 9\n"
                  "2 0 0 0.0 0.0 0.0 9 9 9\n"
                  "4 0 1 2 3 0.25 0.5 0.75 0.3\n"
                  "3 1 4 2 1 2 3 0.9\n");
    const TriangleMeshData mesh = load_mesh(path, kSceneLoc);
    ASSERT_EQ(mesh.triangle_count(), 3u);
    std::vector<std::string> names;
    for (const MeshAttribute& a : mesh.attributes) names.push_back(a.name);
    EXPECT_EQ(names, (std::vector<std::string>{"vertex_color", "face_color", "face_weight"}));

    const MeshAttribute* colour = find_attribute(mesh, "vertex_color");
    ASSERT_NE(colour, nullptr);
    EXPECT_FALSE(colour->per_face);
    ASSERT_EQ(colour->values.size(), 3u * 3u * 3u);
    // Each triangle's corners in its index order: corner k of triangle t has the colour of
    // vertex indices[3 t + k].
    const float vertex_colours[5][3] = {
        {0.1f, 0.2f, 0.3f}, {0.4f, 0.5f, 0.6f}, {0.7f, 0.8f, 0.9f}, {1.f, 1.1f, 1.2f}, {0, 0, 0}};
    for (std::size_t t = 0; t < 3; ++t)
        for (std::size_t k = 0; k < 3; ++k)
            for (std::size_t c = 0; c < 3; ++c)
                EXPECT_FLOAT_EQ(colour->values[(3 * t + k) * 3 + c],
                                vertex_colours[mesh.indices[3 * t + k]][c]);
    // Interpolated with the barycentrics (b1, b2) of corners 1 and 2.
    const Rgb mid = colour->eval(0, Vec2f(0.25f, 0.5f));
    for (int c = 0; c < 3; ++c)
        EXPECT_NEAR(mid[c],
                    0.25f * vertex_colours[mesh.indices[0]][c] +
                        0.25f * vertex_colours[mesh.indices[1]][c] +
                        0.5f * vertex_colours[mesh.indices[2]][c],
                    1e-6f);

    const MeshAttribute* face = find_attribute(mesh, "face_color");
    ASSERT_NE(face, nullptr);
    EXPECT_TRUE(face->per_face);
    EXPECT_TRUE((face->eval(0, Vec2f(0.1f, 0.1f)) == Rgb(0.25f, 0.5f, 0.75f)).all());
    EXPECT_TRUE(
        (face->eval(1, Vec2f(0.7f, 0.1f)) == Rgb(0.25f, 0.5f, 0.75f)).all());  // the quad's second
    EXPECT_TRUE((face->eval(2, Vec2f(0.3f, 0.3f)) == Rgb(1.f, 2.f, 3.f)).all());
    const MeshAttribute* weight = find_attribute(mesh, "face_weight");
    ASSERT_NE(weight, nullptr);
    EXPECT_EQ(weight->dim, 1);
    EXPECT_TRUE(
        (weight->eval(2, Vec2f(0.3f, 0.3f)) == Rgb::Constant(0.9f)).all());  // one field: grey
}

TEST(MeshIo, LoadsBinaryPlyQuads) {
    const TempDir dir;
    std::string contents =
        "ply\nformat binary_little_endian 1.0\nelement vertex 4\n"
        "property float x\nproperty float y\nproperty float z\n"
        "element face 1\nproperty list uchar uint vertex_indices\nend_header\n";
    const float positions[12] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
    contents.append(reinterpret_cast<const char*>(positions), sizeof(positions));
    const unsigned char count = 4;
    const std::uint32_t quad[4] = {0, 1, 2, 3};
    contents.append(reinterpret_cast<const char*>(&count), 1);
    contents.append(reinterpret_cast<const char*>(quad), sizeof(quad));
    const TriangleMeshData mesh = load_mesh(dir.write("quad.ply", contents), kSceneLoc);
    EXPECT_EQ(mesh.triangle_count(), 2u);
    EXPECT_NEAR(total_area(mesh), 1.0, 1e-6);
}

TEST(MeshIo, DropsAndCountsDegenerateTriangles) {
    const TempDir dir;
    const std::string path = dir.write("degenerate.obj",
                                       "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\n"
                                       "f 1 2 3\n"    // fine
                                       "f 1 2 4\n"    // collinear: zero area
                                       "f 1 1 3\n");  // repeated vertex
    const TriangleMeshData mesh = load_mesh(path, kSceneLoc);
    EXPECT_EQ(mesh.triangle_count(), 1u);
    EXPECT_EQ(mesh.degenerate_triangles_dropped, 2u);
}

TEST(MeshIo, NanVertexInObjIsAnInputError) {
    const TempDir dir;
    load_error(dir.write("nan.obj", "v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"));
}

TEST(MeshIo, NanVertexInBinaryPlyIsAnInputErrorNamingTheVertex) {
    const TempDir dir;
    std::string contents =
        "ply\nformat binary_little_endian 1.0\nelement vertex 3\n"
        "property float x\nproperty float y\nproperty float z\n"
        "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const float positions[9] = {0, 0, 0, 1, 0, 0, 0, nan, 0};
    contents.append(reinterpret_cast<const char*>(positions), sizeof(positions));
    const unsigned char count = 3;
    const std::int32_t triangle[3] = {0, 1, 2};
    contents.append(reinterpret_cast<const char*>(&count), 1);
    contents.append(reinterpret_cast<const char*>(triangle), sizeof(triangle));
    const std::string message = load_error(dir.write("nan.ply", contents));
    EXPECT_NE(message.find("vertex 2"), std::string::npos) << message;
    EXPECT_NE(message.find("non-finite"), std::string::npos) << message;
}

TEST(MeshIo, PlyPropertyBeforeAnyElementIsAnInputError) {
    // Crashed CGAL's header reader (a property added to the last of no elements); found by the
    // loader fuzzer as a comment line whose newline had become a vertical tab, swallowing the
    // first element line.
    const TempDir dir;
    const std::string message =
        load_error(dir.write("order.ply",
                             "ply\nformat ascii 1.0\nproperty float x\nelement vertex 3\n"
                             "property float y\nproperty float z\nelement face 1\n"
                             "property list uchar int vertex_indices\nend_header\n"
                             "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"));
    EXPECT_NE(message.find("line 3"), std::string::npos) << message;
}

TEST(MeshIo, AnUnknownPlyElementWithoutPropertiesIsSkippedWhateverItsCount) {
    // 2^40 items of nothing: the loader counted through them one by one (a hang, found by the
    // loader fuzzer). They occupy no bytes, so the mesh after them loads.
    const TempDir dir;
    const auto start = std::chrono::steady_clock::now();
    const TriangleMeshData mesh =
        load_mesh(dir.write("empty_element.ply",
                            "ply\nformat ascii 1.0\nelement junk 1099511627776\nelement vertex 3\n"
                            "property float x\nproperty float y\nproperty float z\nelement face 1\n"
                            "property list uchar int vertex_indices\nend_header\n"
                            "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"),
                  kSceneLoc);
    EXPECT_EQ(mesh.triangle_count(), 1u);
    EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 1.0);
}

/// Peak resident memory of this process so far, in bytes.
double peak_rss_bytes() {
    rusage usage{};
    ::getrusage(RUSAGE_SELF, &usage);
    return static_cast<double>(usage.ru_maxrss) * 1024.0;  // Linux: kilobytes
}

TEST(MeshIo, APlyListCountIsNeitherTrustedWithMemoryNorAllowedNegative) {
    // CGAL's list reader resized its buffer to the count before reading an item: a negative
    // count threw length_error (an "internal error"), a count of 2^31 - 1 one-byte indices
    // zero-filled 2 GB. Both files are truncated, so both are input errors, and the second
    // must not raise the peak memory by more than 256 MB (the fix allocates a few bytes; the
    // bug 2 GB).
    const TempDir dir;
    const std::string header =
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
        "property float y\nproperty float z\nelement face 1\n";
    const std::string vertices = "0 0 0\n1 0 0\n0 1 0\n";
    load_error(dir.write(
        "negative.ply",
        header + "property list int int vertex_indices\nend_header\n" + vertices + "-1 0 1 2\n"));
    const double peak_before = peak_rss_bytes();
    load_error(dir.write("huge.ply", header +
                                         "property list uint uchar vertex_indices\nend_header\n" +
                                         vertices + "2147483647 0 1 2\n"));
    EXPECT_LT(peak_rss_bytes() - peak_before, 256.0 * 1024 * 1024);
}

TEST(MeshIo, MissingFileIsAnInputError) {
    const TempDir dir;
    load_error((dir.path() / "missing.obj").string());
}

TEST(MeshIo, AFifoOrADeviceIsAnInputErrorNotAHang) {
    // Reading a FIFO blocks until a writer opens it, and a device never ends; both must be
    // refused as "not a regular file" (a FIFO used to be reported as "file not found").
    const TempDir dir;
    const fs::path fifo = dir.path() / "mesh.obj";
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    const std::string message = load_error(fifo.string());
    EXPECT_NE(message.find("not a regular file"), std::string::npos) << message;
    fs::create_symlink("/dev/zero", dir.path() / "zero.ply");
    const std::string device = load_error((dir.path() / "zero.ply").string());
    EXPECT_NE(device.find("not a regular file"), std::string::npos) << device;
}

TEST(MeshIo, FaceIndexOutOfRangeIsAnInputError) {
    const TempDir dir;
    load_error(dir.write("range.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n"));
}

TEST(MeshIo, OffCountsThatLieAreInputErrorsWithTheirLine) {
    // CGAL's reader trusts them: -2^31 vertices in a face ended in "internal error:
    // vector::_M_default_append", 99999999999 in an 800 GB allocation (an abort under ASan).
    const TempDir dir;
    const std::string tri = "0 0 0\n1 0 0\n0 1 0\n";
    const std::vector<std::pair<std::string, std::string>> cases = {
        {"OFF\n3 1 0\n" + tri + "-2147483648 0 1 2\n", "line 6"},
        {"OFF\n3 1 0\n" + tri + "99999999999 0 1 2\n", "line 6"},
        {"OFF\n3 1 0\n" + tri + "4 0 1 2\n", "line 6"},  // more than the vertices
        {"OFF\n3 1 0\n" + tri + "2 0 1\n", "line 6"},
        {"OFF\n3 1 0\n" + tri + "3 0 1\n", "line 6"},  // fewer indices than it says
        {"OFF\n99999999999 1 0\n" + tri + "3 0 1 2\n", "line 2"},
        {"OFF\n3 -1 0\n" + tri, "line 2"},
        {"OFF\n3 2 0\n" + tri + "3 0 1 2\n", "line 2"},  // a face missing
        {"OFF BINARY\n", "line 1"}};
    for (const auto& [text, line] : cases) {
        const std::string message = load_error(dir.write("bad.off", text));
        EXPECT_NE(message.find(line), std::string::npos) << text << " -> " << message;
    }
    // Comments, blank lines and counts on the header's line are still read.
    const TriangleMeshData mesh =
        load_mesh(dir.write("ok.off", "# made here\nOFF 3 1 0\n\n" + tri + "3 0 1 2 # face\n"),
                  FileLoc{"scene.xml", 1, 1});
    EXPECT_EQ(mesh.indices.size(), 3u);
}

TEST(MeshIo, VertexNormalsAreAngleWeighted) {
    // Vertex 0 touches a right-angled triangle facing +z and a 45-degree one facing +x, both of
    // area 1/2: angle weighting gives (pi/4, 0, pi/2) -> (1, 0, 2)/sqrt(5) (area weighting would
    // give (1, 0, 1)/sqrt(2)).
    TriangleMeshData mesh;
    mesh.positions = {Vec3f(0, 0, 0), Vec3f(1, 0, 0), Vec3f(0, 1, 0), Vec3f(0, 1, 1)};
    mesh.indices = {0, 1, 2, 0, 2, 3};
    const std::vector<Vec3f> normals = compute_vertex_normals(mesh);
    ASSERT_EQ(normals.size(), 4u);
    EXPECT_TRUE(normals[0].isApprox(Vec3f(1, 0, 2) / std::sqrt(5.f), 1e-5f)) << normals[0];
    EXPECT_TRUE(normals[1].isApprox(Vec3f(0, 0, 1), 1e-5f)) << normals[1];
    EXPECT_TRUE(normals[3].isApprox(Vec3f(1, 0, 0), 1e-5f)) << normals[3];
    for (const Vec3f& n : normals) EXPECT_NEAR(n.norm(), 1.f, 1e-5f);
}

}  // namespace
}  // namespace gdmlt
