// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Where a texture is looked up, and the mesh attributes (Mitsuba 3's per-vertex and per-face
// values of a PLY file) that a `mesh_attribute` texture reads there.
#include <cstdint>
#include <string>
#include <vector>

#include "core/math/types.h"

namespace gdmlt {

struct SurfaceInteraction;

/// A texture lookup: the surface's texture coordinates, and for mesh attributes the shape,
/// its triangle and the barycentrics (b1, b2) of the point in it (p = (1 - b1 - b2) p0 + b1 p1
/// + b2 p2). Built from a bare uv (implicitly) where only uv textures can be met.
struct TexturePoint {
    Vec2f uv = Vec2f::Zero();
    std::int32_t shape = -1;  // -1: not on a mesh (mesh attributes read as zero)
    std::uint32_t primitive = 0;
    Vec2f barycentric = Vec2f::Zero();
    /// The surface point itself, for what needs its differential geometry (bump maps read
    /// dp/du, dp/dv and the frames); null for a bare uv. Valid while the call lasts.
    const SurfaceInteraction* surface = nullptr;

    TexturePoint() = default;
    TexturePoint(const Vec2f& uv_) : uv(uv_) {}  // NOLINT: implicit on purpose
    TexturePoint(float u, float v) : uv(u, v) {}
    TexturePoint(const Vec2f& uv_, std::int32_t shape_, std::uint32_t primitive_,
                 const Vec2f& barycentric_, const SurfaceInteraction* surface_ = nullptr)
        : uv(uv_),
          shape(shape_),
          primitive(primitive_),
          barycentric(barycentric_),
          surface(surface_) {}
};

/// One named attribute of a mesh, `dim` (1 or 3) floats per value, stored per triangle: a face
/// attribute's value, or a vertex attribute's three corner values (so that triangulation and
/// dropped triangles need no index lookups at render time).
struct MeshAttribute {
    std::string name;  // "vertex_color", "face_weight", ... (Mitsuba 3's names)
    int dim = 3;
    bool per_face = false;
    std::vector<float> values;  // per_face: dim per triangle; else 3 * dim per triangle

    /// The value at a point of triangle `triangle` (vertex attributes interpolated
    /// linearly); a one-float attribute is grey.
    Rgb eval(std::uint32_t triangle, const Vec2f& barycentric) const {
        const auto d = static_cast<std::size_t>(dim);
        Rgb out = Rgb::Zero();
        if (per_face) {
            const float* v = values.data() + static_cast<std::size_t>(triangle) * d;
            for (std::size_t c = 0; c < 3; ++c) out[static_cast<int>(c)] = v[d == 1 ? 0 : c];
            return out;
        }
        const float* v = values.data() + static_cast<std::size_t>(triangle) * 3 * d;
        const float w[3] = {1.f - barycentric.x() - barycentric.y(), barycentric.x(),
                            barycentric.y()};
        for (std::size_t c = 0; c < 3; ++c) {
            const std::size_t k = d == 1 ? 0 : c;
            out[static_cast<int>(c)] = w[0] * v[k] + w[1] * v[d + k] + w[2] * v[2 * d + k];
        }
        return out;
    }
};

}  // namespace gdmlt
