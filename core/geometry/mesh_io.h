// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Triangle meshes from files (OBJ, PLY, OFF, Mitsuba's .serialized). CGAL and zlib appear only
// in mesh_io.cpp.
#include <cstdint>
#include <string>
#include <vector>

#include "core/math/types.h"
#include "core/scene/scene_desc.h"
#include "core/texture/texture_point.h"

namespace gdmlt {

/// Plain triangle soup in object space, as loaded: no transform applied.
struct TriangleMeshData {
    std::vector<Vec3f> positions;
    std::vector<Vec3f> normals;          // per vertex, unit length; empty when the mesh has none
    std::vector<Vec2f> uvs;              // per vertex; empty when the mesh has none
    std::vector<std::uint32_t> indices;  // 3 per triangle, counter-clockwise = front
    std::size_t degenerate_triangles_dropped = 0;
    /// The file asks for face normals (a .serialized mesh's flag 0x0010).
    bool face_normals = false;
    /// PLY files' extra vertex and face properties (Mitsuba 3's mesh attributes), per triangle.
    std::vector<MeshAttribute> attributes;

    std::size_t triangle_count() const { return indices.size() / 3; }
};

/// Loads a mesh file, choosing the reader by extension (.obj, .ply, .off, .serialized;
/// case-insensitive); `shape_index` picks one of the meshes a .serialized file holds.
/// Polygons are triangulated. Triangles with (near-)zero area or repeated vertices are dropped
/// and counted. Throws InputError naming `loc` (where the scene asked for the file) and the
/// mesh file when the file is missing or unreadable, has no triangles, or has a non-finite
/// vertex position.
TriangleMeshData load_mesh(const std::string& path, const FileLoc& loc, int shape_index = 0);

/// Area-weighted (by angle) smooth vertex normals for a mesh that has none.
std::vector<Vec3f> compute_vertex_normals(const TriangleMeshData& mesh);

}  // namespace gdmlt
