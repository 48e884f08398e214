// SPDX-License-Identifier: GPL-3.0-or-later
// The manifold walk on configurations with known answers (planar mirror, glass slab, sphere
// reflection and refraction: each solution constructed analytically in this file, independent
// of the module), reversibility, and stress cases that must end with the right named failure,
// bounded iterations and no NaN or Inf.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "manifold/chain_trace.h"
#include "manifold/generalized_geometry.h"
#include "manifold/manifold_walk.h"
#include "manifold/walk_stats.h"
#include "tests/support/scene_fixtures.h"

namespace gdmlt::manifold {
namespace {

std::string fmt(double v) {
    std::ostringstream s;
    s.precision(17);
    s << v;
    return s.str();
}

const char* kMirror = R"(<bsdf type="conductor"/>)";
std::string glass(double int_ior) {
    return R"(<bsdf type="dielectric"><float name="int_ior" value=")" + fmt(int_ior) +
           R"("/><float name="ext_ior" value="1"/></bsdf>)";
}

/// A horizontal rectangle of half-size `half` at height z; normal +z, or -z when `down`.
std::string plane_xml(double z, double half, const std::string& bsdf, bool down = false) {
    return R"(<shape type="rectangle"><transform name="to_world"><scale value=")" + fmt(half) +
           R"("/>)" + (down ? R"(<rotate x="1" angle="180"/>)" : "") +
           R"(<translate value="0, 0, )" + fmt(z) + R"("/></transform>)" + bsdf + "</shape>";
}

std::string sphere_xml(double radius, const std::string& bsdf) {
    return R"(<shape type="sphere"><float name="radius" value=")" + fmt(radius) + R"("/>)" + bsdf +
           "</shape>";
}

/// Refraction of the unit direction w_i (pointing back to where light came from) through the
/// normal n (any orientation) with eta' = eta_out / eta_in; zero on total internal reflection.
Vec3d refract(const Vec3d& w_i, Vec3d n, double eta) {
    if (w_i.dot(n) < 0.0) n = -n;
    const double cos_i = w_i.dot(n);
    const double sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if (sin2_t >= 1.0) return Vec3d::Zero();
    return -w_i / eta + (cos_i / eta - std::sqrt(1.0 - sin2_t)) * n;
}

Vec3d reflect(const Vec3d& w_i, const Vec3d& n) {
    return 2.0 * w_i.dot(n) * n - w_i;
}

SpecularChain traced(const Scene& scene, const Vec3d& start, const Vec3d& aim,
                     std::vector<Scatter> scatters, double end_distance) {
    const ChainOutcome c = trace_new_chain(scene, point_endpoint(start), (aim - start).normalized(),
                                           scatters, end_distance);
    EXPECT_TRUE(c.ok()) << to_string(c.failure);
    return c.chain;
}

void expect_finite(const WalkResult& r) {
    EXPECT_TRUE(std::isfinite(r.relative_distance));
    EXPECT_TRUE(r.chain.start.p.allFinite());
    EXPECT_TRUE(r.chain.end.p.allFinite());
    for (const ChainVertex& v : r.chain.vertices) {
        EXPECT_TRUE(v.geometry.p.allFinite());
        EXPECT_TRUE(v.geometry.n_shading.allFinite());
    }
}

/// Walks to the target, checks the vertices against the expected ones, walks back and checks
/// that the base chain is recovered (the reversibility a shift's invertibility relies on).
WalkResult walk_and_check(const Scene& scene, const SpecularChain& base, const Vec3d& target,
                          const std::vector<Vec3d>& expected, double tolerance) {
    const WalkResult r = walk(scene, base, point_endpoint(target));
    expect_finite(r);
    EXPECT_TRUE(r.ok()) << to_string(r.failure);
    if (!r.ok()) return r;
    EXPECT_EQ(r.chain.size(), expected.size());
    for (std::size_t i = 0; i < expected.size(); ++i)
        EXPECT_LT((r.chain.vertices[i].geometry.p - expected[i]).norm(), tolerance)
            << "vertex " << i << ": " << r.chain.vertices[i].geometry.p.transpose() << " vs "
            << expected[i].transpose();
    // The way back at a tighter tolerance: the vertices then return to within the test's
    // tolerance whatever the conditioning of the chain.
    ManifoldConfig tight;
    tight.relative_tolerance = 1e-12;
    const WalkResult back = walk(scene, r.chain, point_endpoint(base.end.p), tight);
    EXPECT_TRUE(back.ok()) << to_string(back.failure);
    if (back.ok()) {
        for (std::size_t i = 0; i < base.size(); ++i)
            EXPECT_LT((back.chain.vertices[i].geometry.p - base.vertices[i].geometry.p).norm(),
                      tolerance);
    }
    return r;
}

// --- analytic configurations -------------------------------------------------------------------

TEST(ManifoldWalk, PlanarMirrorConvergesToTheMirrorImageSolution) {
    const Scene scene = test::scene_from_xml(plane_xml(0.0, 10.0, kMirror));
    const Vec3d start(-1.0, 0.3, 1.0);
    const SpecularChain base =
        traced(scene, start, Vec3d(0.2, -0.1, 0.0), {Scatter::Reflection}, 2.0);
    const Vec3d target(1.2, -0.5, 2.0);
    // The reflection point lies on the segment from the mirror image of the start to the target.
    const Vec3d image(start.x(), start.y(), -start.z());
    const Vec3d expected = image + (target - image) * (start.z() / (start.z() + target.z()));
    const WalkResult r = walk_and_check(scene, base, target, {expected}, 1e-8);
    // Newton on a projective map: quadratic convergence, 4 projections to 1e-9 here.
    EXPECT_LE(r.iterations, 5);
}

/// Lateral distance covered through a slab (heights above / inside / below) for incidence
/// angle theta, by Snell's law; solved for theta by bisection.
double slab_incidence(double distance, double above, double thickness, double below, double eta) {
    double lo = 0.0, hi = std::numbers::pi / 2 - 1e-12;
    for (int i = 0; i < 200; ++i) {
        const double theta = 0.5 * (lo + hi);
        const double theta_t = std::asin(std::sin(theta) / eta);
        const double d = (above + below) * std::tan(theta) + thickness * std::tan(theta_t);
        (d < distance ? lo : hi) = theta;
    }
    return 0.5 * (lo + hi);
}

void check_slab(double eta, int max_iterations) {
    const Scene scene = test::scene_from_xml(plane_xml(0.0, 50.0, glass(eta)) +
                                             plane_xml(-1.0, 50.0, glass(eta), true));
    const Vec3d start(0.0, 0.0, 1.0);
    const SpecularChain base = traced(scene, start, Vec3d(0.1, 0.05, 0.0),
                                      {Scatter::Refraction, Scatter::Refraction}, 1.5);
    ASSERT_EQ(base.size(), 2u);
    EXPECT_NEAR(base.vertices[0].eta, eta, 1e-6);
    EXPECT_NEAR(base.vertices[1].eta, 1.0 / eta, 1e-6);
    const Vec3d target(0.8, 0.3, -2.0);
    const Vec2d lateral(target.x(), target.y());
    const double theta = slab_incidence(lateral.norm(), 1.0, 1.0, 1.0, eta);
    const double theta_t = std::asin(std::sin(theta) / eta);
    const Vec2d dir = lateral.normalized();
    const Vec2d p1 = dir * std::tan(theta);
    const Vec2d p2 = p1 + dir * std::tan(theta_t);
    const WalkResult r = walk_and_check(
        scene, base, target, {Vec3d(p1.x(), p1.y(), 0.0), Vec3d(p2.x(), p2.y(), -1.0)}, 1e-8);
    EXPECT_LE(r.iterations, max_iterations) << "eta " << eta;
}

TEST(ManifoldWalk, GlassSlabConvergesToTheSnellSolution) {
    check_slab(1.5, 5);
}

TEST(ManifoldWalk, SphereReflectionConvergesToTheConstructedSolution) {
    const Scene scene = test::scene_from_xml(sphere_xml(1.0, kMirror));
    const Vec3d start(3.0, 0.2, 0.5);
    const Vec3d x1 = Vec3d(1.0, 0.4, 0.3).normalized();
    const Vec3d target = x1 + 2.5 * reflect((start - x1).normalized(), x1);
    const SpecularChain base =
        traced(scene, start, Vec3d(1.0, 0.3, 0.45).normalized(), {Scatter::Reflection}, 2.5);
    const WalkResult r = walk_and_check(scene, base, target, {x1}, 1e-8);
    EXPECT_LE(r.iterations, 5);
}

TEST(ManifoldWalk, SphereRefractionConvergesToTheConstructedSolution) {
    const double eta = 1.5;
    const Scene scene = test::scene_from_xml(sphere_xml(1.0, glass(eta)));
    const Vec3d start(0.3, 0.2, 4.0);
    const Vec3d x1 = Vec3d(0.25, 0.1, 1.0).normalized();
    const Vec3d inside = refract((start - x1).normalized(), x1, eta).normalized();
    const Vec3d x2 = x1 - 2.0 * x1.dot(inside) * inside;  // the chord of the unit sphere
    const Vec3d out = refract(-inside, x2, 1.0 / eta);
    ASSERT_FALSE(out.isZero());
    const Vec3d target = x2 + 2.0 * out.normalized();
    const SpecularChain base = traced(scene, start, Vec3d(0.15, 0.05, 0.9),
                                      {Scatter::Refraction, Scatter::Refraction}, 2.0);
    const WalkResult r = walk_and_check(scene, base, target, {x1, x2}, 1e-8);
    EXPECT_LE(r.iterations, 6);
}

TEST(ManifoldWalk, CylinderRefractionConvergesToTheConstructedSolution) {
    // Through a glass cylinder of radius 1 along z (Mitsuba's cylinder, open far beyond the
    // chain): in at x1, out at x2 across the chord, on to the target.
    const double eta = 1.5;
    const Scene scene = test::scene_from_xml(
        R"(<shape type="cylinder"><point name="p0" value="0, 0, -3"/><point name="p1" value="0, 0, 3"/>)" +
        glass(eta) + "</shape>");
    const Vec3d start(0.3, 4.0, 0.6);
    const Vec3d x1 = Vec3d(Vec3d(0.25, 1.0, 0.0).normalized()) + Vec3d(0.0, 0.0, 0.4);
    const auto normal = [](const Vec3d& p) { return Vec3d(p.x(), p.y(), 0.0); };
    const Vec3d inside = refract((start - x1).normalized(), normal(x1), eta).normalized();
    const Vec3d flat(inside.x(), inside.y(), 0.0);
    const Vec3d x2 = x1 - 2.0 * normal(x1).dot(flat) / flat.squaredNorm() * inside;
    const Vec3d out = refract(-inside, normal(x2), 1.0 / eta);
    ASSERT_FALSE(out.isZero());
    const Vec3d target = x2 + 2.0 * out.normalized();
    const SpecularChain base = traced(scene, start, Vec3d(0.1, 0.9, 0.35),
                                      {Scatter::Refraction, Scatter::Refraction}, 2.0);
    const WalkResult r = walk_and_check(scene, base, target, {x1, x2}, 1e-8);
    EXPECT_LE(r.iterations, 6);
}

TEST(ManifoldWalk, TangentMapMatchesFiniteDifferencesOfWalks) {
    // T_1 = d x_1 / d x_end from the block solve, against walks of the end by +-h: each walk to
    // 1e-13 of the chain length, h = 1e-6, so solver noise is ~1e-7 relative.
    const Scene scene = test::scene_from_xml(sphere_xml(1.0, glass(1.5)));
    const SpecularChain base = traced(scene, Vec3d(0.3, 0.2, 4.0), Vec3d(0.15, 0.05, 0.9),
                                      {Scatter::Refraction, Scatter::Refraction}, 2.0);
    const Tangents et = end_tangents(base);
    const auto t1 = first_vertex_tangent_map(base, et);
    ASSERT_TRUE(t1.has_value());
    ManifoldConfig config;
    config.relative_tolerance = 1e-13;
    constexpr double h = 1e-6;
    Mat2d fd;
    for (int c = 0; c < 2; ++c) {
        const WalkResult plus = walk(scene, base, point_endpoint(base.end.p + h * et[c]), config);
        const WalkResult minus = walk(scene, base, point_endpoint(base.end.p - h * et[c]), config);
        ASSERT_TRUE(plus.ok() && minus.ok());
        const Vec3d d = plus.chain.vertices[0].geometry.p - minus.chain.vertices[0].geometry.p;
        const Tangents& t = base.vertices[0].geometry.tangents;
        fd.col(c) = Vec2d(t[0].dot(d), t[1].dot(d)) / (2 * h);
    }
    EXPECT_LT((fd - *t1).norm(), 1e-5 * t1->norm()) << fd << "\n" << *t1;
}

// --- stress ------------------------------------------------------------------------------------

TEST(ManifoldWalkStress, EtaCloseToOneAndIndexMatched) {
    check_slab(1.0001, 5);
    check_slab(1.0, 5);  // index matched: the chain is a straight line through the slab
}

TEST(ManifoldWalkStress, SceneScaleDoesNotChangeIterationsOrRelativeAccuracy) {
    int reference_iterations = -1;
    for (const double s : {1e-3, 1.0, 1e3}) {
        const Scene scene = test::scene_from_xml(sphere_xml(s, kMirror));
        // The scene stores the radius in float: construct the solution on that sphere.
        const double radius = static_cast<double>(static_cast<float>(s));
        const Vec3d start = s * Vec3d(3.0, 0.2, 0.5);
        const Vec3d x1 = radius * Vec3d(1.0, 0.4, 0.3).normalized();
        const Vec3d target = x1 + 2.5 * s * reflect((start - x1).normalized(), x1.normalized());
        const SpecularChain base = traced(scene, start, s * Vec3d(1.0, 0.3, 0.45).normalized(),
                                          {Scatter::Reflection}, 2.5 * s);
        const WalkResult r = walk_and_check(scene, base, target, {x1}, 1e-8 * s);
        if (reference_iterations < 0) reference_iterations = r.iterations;
        EXPECT_NEAR(r.iterations, reference_iterations, 1) << "scale " << s;
        const LogTerm g = log_generalized_geometry_term(r.chain);
        ASSERT_TRUE(g.ok());
        EXPECT_TRUE(std::isfinite(g.log_value));
    }
}

TEST(ManifoldWalkStress, GrazingIncidenceOnAPlanarMirror) {
    const Scene scene = test::scene_from_xml(plane_xml(0.0, 1000.0, kMirror));
    const Vec3d start(0.0, 0.0, 1.0);
    const SpecularChain base =
        traced(scene, start, Vec3d(20.0, 0.0, 0.0), {Scatter::Reflection}, 5.0);
    // Reflection at about 89.8 degrees from the normal.
    const Vec3d target(400.0, 0.0, 0.5);
    const Vec3d image(0.0, 0.0, -1.0);
    const Vec3d expected = image + (target - image) * (1.0 / 1.5);
    const WalkResult r = walk(scene, base, point_endpoint(target));
    expect_finite(r);
    ASSERT_TRUE(r.ok()) << to_string(r.failure);
    EXPECT_LT((r.chain.vertices[0].geometry.p - expected).norm(), 1e-9 * 400.0);
    EXPECT_LE(r.iterations, 12);
    const LogTerm g = log_generalized_geometry_term(r.chain);
    ASSERT_TRUE(g.ok());
    EXPECT_TRUE(std::isfinite(g.log_value));
}

TEST(ManifoldWalkStress, NearTotalInternalReflectionStepsBackAndConverges) {
    // Light leaves glass through a plane; the base exits at 30 degrees inside, the target needs
    // an exit close to grazing (inside angle within 0.02 degrees of critical). Newton steps that
    // overshoot into total internal reflection are rejected and the step halves.
    const double eta = 1.5;
    const Scene scene = test::scene_from_xml(plane_xml(0.0, 1000.0, glass(eta)));
    const Vec3d start(0.0, 0.0, -1.0);
    const SpecularChain base =
        traced(scene, start, Vec3d(std::tan(0.5), 0.0, 0.0), {Scatter::Refraction}, 2.0);
    ASSERT_EQ(base.size(), 1u);
    EXPECT_NEAR(base.vertices[0].eta, 1.0 / eta, 1e-6);
    const Vec3d target(60.0, 0.0, 1.0);
    const WalkResult r = walk(scene, base, point_endpoint(target));
    expect_finite(r);
    EXPECT_LE(r.iterations, ManifoldConfig{}.max_iterations);
    // The walk must converge (it used to be allowed to fail with TIR, so the test passed
    // whether or not the step-back worked), and it must have needed the step-back.
    ASSERT_TRUE(r.ok()) << to_string(r.failure);
    EXPECT_GT(r.rejected_steps[static_cast<std::size_t>(WalkFailure::TotalInternalReflection)], 0);
    // Snell at the converged vertex.
    const Vec3d x1 = r.chain.vertices[0].geometry.p;
    const double sin_i = std::sin(std::atan2(x1.x(), 1.0));
    const double sin_t = (target.x() - x1.x()) / (target - x1).norm();
    EXPECT_NEAR(eta * sin_i, sin_t, 1e-9);
}

TEST(ManifoldWalkStress, UnreachableTargetBehindASphereLeavesTheManifold) {
    // A convex mirror cannot reflect light from the front to a point straight behind it: the
    // vertex would have to pass the silhouette.
    const Scene scene = test::scene_from_xml(sphere_xml(1.0, kMirror));
    const Vec3d start(0.0, 0.0, 5.0);
    const SpecularChain base =
        traced(scene, start, Vec3d(0.5, 0.0, 0.8), {Scatter::Reflection}, 3.0);
    const WalkResult r = walk(scene, base, point_endpoint(Vec3d(0.3, 0.0, -5.0)));
    expect_finite(r);
    EXPECT_FALSE(r.ok());
    EXPECT_LE(r.iterations, ManifoldConfig{}.max_iterations);
    // Steps past the silhouette are rejected (LeftManifold); the accepted ones creep towards it
    // with ever smaller gains, so the walk ends by one of these three reasons.
    EXPECT_TRUE(r.failure == WalkFailure::LeftManifold ||
                r.failure == WalkFailure::DistanceIncreased ||
                r.failure == WalkFailure::NotConverged)
        << to_string(r.failure) << " after " << r.iterations << " iterations, distance "
        << r.relative_distance;
    EXPECT_GT(r.rejected_steps[static_cast<std::size_t>(WalkFailure::LeftManifold)], 0);
}

TEST(ManifoldWalkStress, OccludedLastSegmentIsReported) {
    // The mirror solution exists but a small rectangle blocks its last segment.
    const Scene scene = test::scene_from_xml(
        plane_xml(0.0, 10.0, kMirror) +
        R"(<shape type="rectangle"><transform name="to_world"><scale value="0.2"/>
            <rotate y="1" angle="90"/><translate value="0.9, -0.4, 1.5"/></transform></shape>)");
    const SpecularChain base =
        traced(scene, Vec3d(-1.0, 0.3, 1.0), Vec3d(0.2, -0.1, 0.0), {Scatter::Reflection}, 1.0);
    const WalkResult r = walk(scene, base, point_endpoint(Vec3d(1.2, -0.5, 2.0)));
    expect_finite(r);
    EXPECT_EQ(r.failure, WalkFailure::Occluded);
}

TEST(ManifoldWalkStress, IterationCapEndsTheWalkAsNotConverged) {
    const Scene scene = test::scene_from_xml(sphere_xml(1.0, kMirror));
    const SpecularChain base =
        traced(scene, Vec3d(3.0, 0.2, 0.5), Vec3d(1.0, 0.3, 0.45).normalized(),
               {Scatter::Reflection}, 2.5);
    ManifoldConfig config;
    config.max_iterations = 1;
    const WalkResult r =
        walk(scene, base, point_endpoint(base.end.p + Vec3d(0.3, 0.4, -0.2)), config);
    expect_finite(r);
    EXPECT_EQ(r.failure, WalkFailure::NotConverged);
    EXPECT_EQ(r.iterations, 1);
}

TEST(ManifoldWalkStress, FocalPointOfAConcaveMirrorIsASingularMatrix) {
    // Every ray from the centre of a spherical mirror returns to the centre: with the end there
    // the chain is not locally unique (a caustic), G~ is infinite, the system singular.
    const Scene scene = test::scene_from_xml(
        R"(<shape type="sphere"><float name="radius" value="1"/><boolean name="flip_normals" value="true"/>
            <bsdf type="conductor"/></shape>)");
    const SpecularChain chain =
        traced(scene, Vec3d::Zero(), Vec3d(0.3, 0.5, 0.8), {Scatter::Reflection}, 1.0);
    const LogTerm g = log_generalized_geometry_term(chain);
    EXPECT_EQ(g.failure, WalkFailure::SingularMatrix);
    EXPECT_EQ(g.value(), 0.0);
    const WalkResult r = walk(scene, chain, point_endpoint(Vec3d(0.01, 0.02, -0.01)));
    expect_finite(r);
    EXPECT_EQ(r.failure, WalkFailure::SingularMatrix);
}

/// A mirror strip of sliver triangles (aspect ratio 1e4) with smoothly varying vertex normals.
std::string write_sliver_obj() {
    const std::string path = (std::filesystem::temp_directory_path() /
                              ("gdmlt_manifold_slivers_" + std::to_string(::getpid()) + ".obj"))
                                 .string();
    std::ofstream out(path);
    out.precision(17);
    const int columns = 4001;
    for (int i = 0; i < columns; ++i) {
        const double x = -0.2 + 0.4 * i / (columns - 1);
        out << "v " << x << " -2 0\nv " << x << " 2 0\n";
    }
    for (int i = 0; i < columns; ++i) {
        const double x = -0.2 + 0.4 * i / (columns - 1);
        const Vec3d n = Vec3d(0.3 * x, 0.0, 1.0).normalized();  // a gently curved mirror
        out << "vn " << n.x() << ' ' << n.y() << ' ' << n.z() << "\nvn " << n.x() << ' ' << n.y()
            << ' ' << n.z() << '\n';
    }
    for (int i = 0; i + 1 < columns; ++i) {
        const int a = 2 * i + 1, b = a + 1, c = a + 2, d = a + 3;
        out << "f " << a << "//" << a << ' ' << c << "//" << c << ' ' << b << "//" << b << '\n';
        out << "f " << b << "//" << b << ' ' << c << "//" << c << ' ' << d << "//" << d << '\n';
    }
    return path;
}

TEST(ManifoldWalkStress, NearlyDegenerateTrianglesStayFinite) {
    const std::string path = write_sliver_obj();
    const Scene scene =
        test::scene_from_xml(R"(<shape type="obj"><string name="filename" value=")" + path +
                             R"("/><bsdf type="conductor"/></shape>)");
    std::filesystem::remove(path);
    const SpecularChain base =
        traced(scene, Vec3d(-0.5, 0.1, 1.0), Vec3d(-0.05, 0.0, 0.0), {Scatter::Reflection}, 1.0);
    WalkStats stats;
    for (int i = 0; i < 20; ++i) {
        const Vec3d target = base.end.p + Vec3d(0.01 * i, 0.02 * i, 0.005 * i);
        const WalkResult r = walk(scene, base, point_endpoint(target));
        expect_finite(r);
        EXPECT_LE(r.iterations, ManifoldConfig{}.max_iterations);
        stats.record(r);
        if (r.ok()) {
            const LogTerm g = log_generalized_geometry_term(r.chain);
            EXPECT_TRUE(!g.ok() || std::isfinite(g.log_value));
        }
    }
    // Crossing hundreds of slivers: the interpolated normal is only C0 across edges, so Newton
    // may need extra steps, but these targets are all reachable.
    EXPECT_EQ(stats.successes, stats.walks)
        << "not converged " << stats.failure_count(WalkFailure::NotConverged) << ", left "
        << stats.failure_count(WalkFailure::LeftManifold);
}

TEST(WalkStats, CountsOutcomesAndSumsAcrossThreads) {
    WalkResult ok;
    ok.iterations = 3;
    ok.accepted_steps = 3;
    WalkResult failed;
    failed.failure = WalkFailure::LeftManifold;
    failed.iterations = 7;
    failed.rejected_steps[static_cast<std::size_t>(WalkFailure::LeftManifold)] = 4;
    WalkStats a, b;
    a.record(ok);
    b.record(failed);
    a += b;
    EXPECT_EQ(a.walks, 2u);
    EXPECT_EQ(a.successes, 1u);
    EXPECT_EQ(a.failure_count(WalkFailure::LeftManifold), 1u);
    EXPECT_EQ(a.rejected_steps[static_cast<std::size_t>(WalkFailure::LeftManifold)], 4u);
    EXPECT_DOUBLE_EQ(a.mean_iterations(), 5.0);
    EXPECT_DOUBLE_EQ(a.mean_successful_iterations(), 3.0);
    EXPECT_STREQ(to_string(WalkFailure::TotalInternalReflection), "total_internal_reflection");
}

}  // namespace
}  // namespace gdmlt::manifold
