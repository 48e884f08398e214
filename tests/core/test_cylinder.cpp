// SPDX-License-Identifier: GPL-3.0-or-later
// Mitsuba 3's `cylinder` (core/geometry/shape.h): hits against the analytic answer (from outside,
// through an open end onto the inner wall, missing past an end), Mitsuba's uv and outward
// normals, flip_normals and a negative radius, p0/p1 with to_world, uniform area sampling
// (chi-square over (phi, z)), and the input errors.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "core/scene/scene.h"
#include "core/scene/scene_desc.h"
#include "tests/support/chi2.h"
#include "tests/support/scene_fixtures.h"

namespace gdmlt {
namespace {

/// A scene holding one cylinder described by `body` (the properties inside <shape>).
Scene cylinder_scene(const std::string& body) {
    return test::scene_from_xml(test::sensor_xml(8, 40.f, "0, 0, 10") +
                                "<shape type=\"cylinder\">" + body +
                                "<bsdf type=\"diffuse\"/></shape>");
}

TEST(Cylinder, HitsAtTheAnalyticDistanceWithMitsubasUvAndOutwardNormal) {
    // Radius 0.5 around the z axis from z = 0 to 2 (p1). A ray along -x at height 1.5 from
    // x = 3 meets x = 0.5: t = 2.5, phi = 0, u = 0, v = z / length = 0.75, n = +x.
    const Scene scene =
        cylinder_scene(R"(<float name="radius" value="0.5"/><point name="p1" value="0, 0, 2"/>)");
    const SurfaceInteraction si = scene.intersect(Ray{Vec3f(3.f, 0.f, 1.5f), -Vec3f::UnitX()});
    ASSERT_TRUE(si.valid());
    EXPECT_NEAR(si.t, 2.5f, 1e-5f);
    EXPECT_TRUE(si.p.isApprox(Vec3f(0.5f, 0.f, 1.5f), 1e-5f)) << si.p.transpose();
    EXPECT_NEAR(si.uv.y(), 0.75f, 1e-5f);
    EXPECT_NEAR(std::min(si.uv.x(), 1.f - si.uv.x()), 0.f, 1e-5f);
    EXPECT_TRUE(si.n_geometric.isApprox(Vec3f::UnitX(), 1e-5f)) << si.n_geometric.transpose();
    EXPECT_TRUE(si.shading.n.isApprox(si.n_geometric, 1e-5f));
    // dp/du runs along the circle (counter-clockwise about the axis), 2 pi r long.
    EXPECT_TRUE(si.dp_du.isApprox(Vec3f(0.f, kPi, 0.f), 1e-4f)) << si.dp_du.transpose();
    EXPECT_TRUE(si.dp_dv.isApprox(Vec3f(0.f, 0.f, 2.f), 1e-5f)) << si.dp_dv.transpose();

    // At phi = 90 degrees (from +y): u = 1/4.
    const SurfaceInteraction side = scene.intersect(Ray{Vec3f(0.f, 4.f, 0.5f), -Vec3f::UnitY()});
    ASSERT_TRUE(side.valid());
    EXPECT_NEAR(side.t, 3.5f, 1e-5f);
    EXPECT_NEAR(side.uv.x(), 0.25f, 1e-5f);
    EXPECT_TRUE(side.n_geometric.isApprox(Vec3f::UnitY(), 1e-5f));
}

TEST(Cylinder, IsOpenAtItsEnds) {
    const Scene scene =
        cylinder_scene(R"(<float name="radius" value="0.5"/><point name="p1" value="0, 0, 2"/>)");
    // Down the axis: no wall in the way.
    EXPECT_FALSE(scene.intersect(Ray{Vec3f(0.f, 0.f, 5.f), -Vec3f::UnitZ()}).valid());
    // Past the top: misses.
    EXPECT_FALSE(scene.intersect(Ray{Vec3f(3.f, 0.f, 2.2f), -Vec3f::UnitX()}).valid());
    // Into the open top, steeply: the inner wall at x = 0.5, reached at z = 2.5 - 4 x 0.5; its
    // outward normal faces along the ray (seen from inside).
    const Vec3f steep = Vec3f(1.f, 0.f, -4.f).normalized();
    const SurfaceInteraction wall = scene.intersect(Ray{Vec3f(0.f, 0.f, 2.5f), steep});
    ASSERT_TRUE(wall.valid());
    EXPECT_NEAR(wall.p.z(), 0.5f, 1e-4f);
    EXPECT_GT(wall.n_geometric.dot(steep), 0.f);  // seen from inside
}

TEST(Cylinder, FlipNormalsAndANegativeRadiusTurnTheNormalInwards) {
    for (const char* body :
         {R"(<float name="radius" value="0.5"/><boolean name="flip_normals" value="true"/>)",
          R"(<float name="radius" value="-0.5"/>)"}) {
        const Scene scene = cylinder_scene(body);
        const SurfaceInteraction si = scene.intersect(Ray{Vec3f(3.f, 0.f, 0.5f), -Vec3f::UnitX()});
        ASSERT_TRUE(si.valid()) << body;
        EXPECT_NEAR(si.t, 2.5f, 1e-5f) << body;
        EXPECT_TRUE(si.n_geometric.isApprox(-Vec3f::UnitX(), 1e-5f)) << body;
    }
}

TEST(Cylinder, P0P1AndToWorldPlaceTheAxis) {
    // From (1, 1, 0) to (1, 1 + 3, 0) along +y, radius 0.25, then moved by +2 in z.
    const Scene scene = cylinder_scene(
        R"(<float name="radius" value="0.25"/><point name="p0" value="1, 1, 0"/>
           <point name="p1" value="1, 4, 0"/>
           <transform name="to_world"><translate z="2"/></transform>)");
    const SurfaceInteraction si = scene.intersect(Ray{Vec3f(1.f, 2.f, 10.f), -Vec3f::UnitZ()});
    ASSERT_TRUE(si.valid());
    EXPECT_NEAR(si.p.z(), 2.25f, 1e-5f);
    EXPECT_NEAR(si.uv.y(), 1.f / 3.f, 1e-5f);
    EXPECT_TRUE(si.n_geometric.isApprox(Vec3f::UnitZ(), 1e-5f));
    EXPECT_NEAR(scene.shapes()[0].surface_area(), 2.f * kPi * 0.25f * 3.f, 1e-5f);
    EXPECT_FALSE(scene.intersect(Ray{Vec3f(1.f, 4.5f, 10.f), -Vec3f::UnitZ()}).valid());
}

TEST(Cylinder, AreaSamplesAreUniformOverTheWall) {
    // Seed 9, 200000 samples into 16 x 8 bins of (phi, z) on a cylinder along a slanted axis:
    // each bin expects 1/128 of them (Pearson's chi-square at the suite's Sidak level). The
    // samples must lie on the wall, with the outward normal.
    const Scene scene = cylinder_scene(
        R"(<float name="radius" value="0.3"/><point name="p0" value="-1, 0, 0"/>
           <point name="p1" value="1, 1, 0.5"/>)");
    const Shape& shape = scene.shapes()[0];
    const auto& cylinder = std::get<Cylinder>(shape.geometry());
    const int bins_phi = 16, bins_z = 8, n = 200000;
    std::vector<double> observed(bins_phi * bins_z, 0.0);
    Pcg32 rng(9, 3);
    for (int i = 0; i < n; ++i) {
        const ShapeSample s =
            shape.sample_area({rng.next_float(), rng.next_float()}, rng.next_float());
        ASSERT_NEAR(s.pdf_area, 1.f / shape.surface_area(), 1e-6f);
        const Vec3f local = cylinder.to_object(s.p);
        ASSERT_NEAR(std::hypot(local.x(), local.y()), 1.f, 1e-4f);
        const Vec3f outward = (cylinder.linear * Vec3f(local.x(), local.y(), 0.f)).normalized();
        ASSERT_TRUE(s.n_geometric.isApprox(outward, 1e-4f));
        float phi = std::atan2(local.y(), local.x());
        if (phi < 0.f) phi += 2.f * kPi;
        const int bx = std::min(static_cast<int>(phi / (2.f * kPi) * bins_phi), bins_phi - 1);
        const int bz = std::clamp(static_cast<int>(local.z() * bins_z), 0, bins_z - 1);
        observed[static_cast<std::size_t>(bz * bins_phi + bx)] += 1.0;
    }
    const std::vector<double> expected(observed.size(), static_cast<double>(n) / observed.size());
    const test::Chi2Result r = test::chi2_histogram_test(observed, expected);
    EXPECT_GT(r.p_value, test::sidak_alpha(1)) << r.summary;
}

TEST(Cylinder, ATransformThatWouldMakeItEllipticOrAZeroAxisIsAnInputError) {
    EXPECT_THROW(
        cylinder_scene(R"(<transform name="to_world"><scale x="2" y="1" z="1"/></transform>)"),
        InputError);
    EXPECT_THROW(
        cylinder_scene(R"(<point name="p0" value="0, 0, 1"/><point name="p1" value="0, 0, 1"/>)"),
        InputError);
    EXPECT_THROW(cylinder_scene(R"(<float name="radius" value="0"/>)"), InputError);
    // A uniform scale and a scale along the axis keep it round.
    EXPECT_NO_THROW(
        cylinder_scene(R"(<transform name="to_world"><scale x="2" y="2" z="5"/></transform>)"));
}

}  // namespace
}  // namespace gdmlt
