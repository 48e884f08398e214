// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// A point on a surface with the differential geometry later modules need (the manifold walk
// moves along surfaces through dp/du, dp/dv, dn/du, dn/dv).
#include <cstdint>

#include "core/math/frame.h"
#include "core/math/types.h"
#include "core/texture/texture_point.h"

namespace gdmlt {

struct SurfaceInteraction {
    Vec3f p = Vec3f::Zero();             // world position, rebuilt from the surface parameters
    Vec3f n_geometric = Vec3f::UnitZ();  // unit; orientation follows winding / flip_normals
    Frame shading;                       // shading.n: interpolated (or geometric) normal
    Vec3f dp_du = Vec3f::Zero(), dp_dv = Vec3f::Zero();
    Vec3f dn_du = Vec3f::Zero(), dn_dv = Vec3f::Zero();  // of the shading normal
    Vec2f uv = Vec2f::Zero();                            // texture coordinates
    /// d uv / d surface_param, columns: (u, v) along the first and the second parameter
    /// (identity where uv is the parametrisation itself; a triangle's uv edges on meshes with
    /// uvs). Bump maps turn dp/du, dp/dv into derivatives in uv with it.
    Vec2f duv_du = Vec2f::UnitX(), duv_dv = Vec2f::UnitY();
    Vec2f surface_param = Vec2f::Zero();  // (u, v) the derivatives above refer to:
                                          // barycentrics (b1, b2) on triangles, (phi/2pi,
                                          // theta/pi) on spheres
    float t = kInfinity;                  // ray distance
    std::int32_t shape = -1;
    std::uint32_t primitive = 0;

    bool valid() const { return shape >= 0; }
    /// Where the surface's textures are looked up (surface_param holds the barycentrics on
    /// triangles, which only mesh attributes read); it points at this interaction, so use it
    /// while this lives.
    TexturePoint texture_point() const { return {uv, shape, primitive, surface_param, this}; }
};

}  // namespace gdmlt
