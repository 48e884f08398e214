// SPDX-License-Identifier: GPL-3.0-or-later
// The algebra of specular chains against independent references: the block-tridiagonal solver
// against dense LU, the constraint derivative blocks and the chain Jacobians against central
// finite differences, on randomized chains of 1 to 6 vertices traced through spheres, glass and a
// smooth-normal mesh (real Shape differential geometry).
//
// Finite-difference steps and tolerances (all in double):
//  - blocks: h = 1e-5 (scenes of unit size). Truncation error O(h^2 |c'''|) ~ 1e-10 / l^3 and
//    round-off ~ 1e-16 / h ~ 1e-11; we assert 1e-6 relative to the largest block of the row.
//  - G~: directions perturbed by h = 1e-6 rad and traced in double; same reasoning, we assert
//    1e-5 on log G~ (1e-5 relative).
//  - half-vector Jacobian: slopes perturbed by h = 1e-6, each perturbed chain solved by a walk to
//    1e-13 of its length, so the solver contributes ~1e-13 / 1e-6 = 1e-7 relative; h = 1e-5 is
//    too coarse for ill-conditioned mesh chains (|det| ~ e^14: truncation 3e-3). We assert 1e-4
//    on the log determinant.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>

#include "manifold/block_tridiagonal.h"
#include "manifold/chain_trace.h"
#include "manifold/constraints.h"
#include "manifold/generalized_geometry.h"
#include "manifold/manifold_walk.h"
#include "manifold/surface_point.h"
#include "tests/support/scene_fixtures.h"

namespace gdmlt::manifold {
namespace {

// --- scenes ------------------------------------------------------------------------------------

/// A subdivided icosahedron of radius 1 with per-vertex normals (smooth shading), as an OBJ file.
std::string write_icosphere_obj(int subdivisions) {
    std::vector<Vec3d> v;
    std::vector<std::array<int, 3>> f;
    const double t = (1.0 + std::sqrt(5.0)) / 2.0;
    for (const Vec3d& p : {Vec3d(-1, t, 0), Vec3d(1, t, 0), Vec3d(-1, -t, 0), Vec3d(1, -t, 0),
                           Vec3d(0, -1, t), Vec3d(0, 1, t), Vec3d(0, -1, -t), Vec3d(0, 1, -t),
                           Vec3d(t, 0, -1), Vec3d(t, 0, 1), Vec3d(-t, 0, -1), Vec3d(-t, 0, 1)})
        v.push_back(p.normalized());
    f = {{0, 11, 5},  {0, 5, 1},  {0, 1, 7},  {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
         {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
         {3, 8, 9},   {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
    for (int s = 0; s < subdivisions; ++s) {
        std::map<std::pair<int, int>, int> midpoint;
        const auto mid = [&](int a, int b) {
            const auto key = std::minmax(a, b);
            const auto it = midpoint.find(key);
            if (it != midpoint.end()) return it->second;
            v.push_back(
                (v[static_cast<std::size_t>(a)] + v[static_cast<std::size_t>(b)]).normalized());
            const int index = static_cast<int>(v.size()) - 1;
            midpoint[key] = index;
            return index;
        };
        std::vector<std::array<int, 3>> next;
        for (const auto& tri : f) {
            const int a = mid(tri[0], tri[1]), b = mid(tri[1], tri[2]), c = mid(tri[2], tri[0]);
            next.push_back({tri[0], a, c});
            next.push_back({tri[1], b, a});
            next.push_back({tri[2], c, b});
            next.push_back({a, b, c});
        }
        f = std::move(next);
    }
    const std::string path = (std::filesystem::temp_directory_path() /
                              ("gdmlt_manifold_icosphere_" + std::to_string(::getpid()) + "_" +
                               std::to_string(subdivisions) + ".obj"))
                                 .string();
    std::ofstream out(path);
    out.precision(17);
    for (const Vec3d& p : v) out << "v " << p.x() << ' ' << p.y() << ' ' << p.z() << '\n';
    for (const Vec3d& p : v) out << "vn " << p.x() << ' ' << p.y() << ' ' << p.z() << '\n';
    for (const auto& tri : f)
        out << "f " << tri[0] + 1 << "//" << tri[0] + 1 << ' ' << tri[1] + 1 << "//" << tri[1] + 1
            << ' ' << tri[2] + 1 << "//" << tri[2] + 1 << '\n';
    return path;
}

enum class ChainKind {
    MirrorSphereInside,
    GlassSphere,
    MirrorMeshInside,
    MirrorCylinderInside,
    MirrorInstanceInside
};
constexpr ChainKind kAllKinds[] = {ChainKind::MirrorSphereInside, ChainKind::GlassSphere,
                                   ChainKind::MirrorMeshInside, ChainKind::MirrorCylinderInside,
                                   ChainKind::MirrorInstanceInside};

const char* name(ChainKind kind) {
    switch (kind) {
        case ChainKind::MirrorSphereInside:
            return "mirror sphere (inside)";
        case ChainKind::GlassSphere:
            return "glass sphere";
        case ChainKind::MirrorMeshInside:
            return "smooth-normal mirror mesh (inside)";
        case ChainKind::MirrorCylinderInside:
            return "mirror cylinder (inside)";
        case ChainKind::MirrorInstanceInside:
            return "smooth-normal mirror mesh instance, mirrored and stretched (inside)";
    }
    return "?";
}

Scene make_scene(ChainKind kind) {
    switch (kind) {
        case ChainKind::MirrorSphereInside:
            return test::scene_from_xml(R"(<shape type="sphere"><float name="radius" value="1"/>
                <boolean name="flip_normals" value="true"/><bsdf type="conductor"/></shape>)");
        case ChainKind::GlassSphere:
            return test::scene_from_xml(R"(<shape type="sphere"><float name="radius" value="1"/>
                <bsdf type="dielectric"><float name="int_ior" value="1.5"/>
                <float name="ext_ior" value="1"/></bsdf></shape>)");
        case ChainKind::MirrorCylinderInside:
            // Long enough that most random chains from near the centre stay inside it.
            return test::scene_from_xml(R"(<shape type="cylinder"><float name="radius" value="1"/>
                <point name="p0" value="0, 0, -4"/><point name="p1" value="0, 0, 4"/>
                <boolean name="flip_normals" value="true"/><bsdf type="conductor"/></shape>)");
        case ChainKind::MirrorMeshInside: {
            // The OBJ file lives only while the scene loads it (the scene keeps the mesh).
            const std::string path = write_icosphere_obj(2);
            Scene scene =
                test::scene_from_xml(R"(<shape type="obj"><string name="filename" value=")" + path +
                                     R"("/><boolean name="flip_normals" value="true"/>
                <bsdf type="conductor"/></shape>)");
            std::filesystem::remove(path);
            return scene;
        }
        case ChainKind::MirrorInstanceInside: {
            // The same mesh in a shapegroup, placed by an instance whose to_world mirrors x and
            // stretches unevenly: the walk reads the shared object-space mesh through the map.
            const std::string path = write_icosphere_obj(2);
            Scene scene = test::scene_from_xml(
                R"(<shape type="shapegroup" id="g"><shape type="obj"><string name="filename" value=")" +
                path + R"("/><boolean name="flip_normals" value="true"/>
                <bsdf type="conductor"/></shape></shape>
                <shape type="instance"><ref id="g"/><transform name="to_world">
                <scale x="-1.3" y="1.1" z="1.2"/><rotate x="1" y="1" angle="30"/>
                <translate value="0.1, 0, -0.2"/></transform></shape>)");
            std::filesystem::remove(path);
            EXPECT_TRUE(scene.shapes().at(0).is_instance());
            return scene;
        }
    }
    return test::scene_from_xml("");
}

Vec3d random_unit(std::mt19937& rng) {
    std::normal_distribution<double> normal;
    for (;;) {
        const Vec3d v(normal(rng), normal(rng), normal(rng));
        if (v.norm() > 1e-3) return v.normalized();
    }
}

/// A random chain of k vertices traced through the scene (retrying until one is found).
std::optional<SpecularChain> random_chain(const Scene& scene, ChainKind kind, int k,
                                          std::mt19937& rng) {
    std::uniform_real_distribution<double> uniform;
    for (int attempt = 0; attempt < 200; ++attempt) {
        ChainEndpoint start;
        Vec3d direction;
        std::vector<Scatter> scatters;
        double end_distance = 0.0;
        if (kind == ChainKind::GlassSphere) {
            start = point_endpoint(3.0 * random_unit(rng));
            const Vec3d aim = 0.85 * uniform(rng) * random_unit(rng);
            direction = (aim - start.p).normalized();
            scatters.push_back(Scatter::Refraction);
            for (int i = 2; i < k; ++i) scatters.push_back(Scatter::Reflection);
            if (k >= 2) scatters.push_back(Scatter::Refraction);
            end_distance = k == 1 ? 0.2 + 0.5 * uniform(rng) : 0.5 + uniform(rng);
        } else {
            start = point_endpoint(0.6 * uniform(rng) * random_unit(rng));
            direction = random_unit(rng);
            scatters.assign(static_cast<std::size_t>(k), Scatter::Reflection);
            end_distance = uniform(rng) < 0.5 ? 0.0 : 0.1 + 0.4 * uniform(rng);
        }
        ChainOutcome c = trace_new_chain(scene, start, direction, scatters, end_distance);
        if (!c.ok()) continue;
        // Avoid near-degenerate random draws (tiny segments, grazing hits): they test the
        // stress cases, not the derivatives.
        bool good = true;
        for (std::size_t i = 0; i + 1 < c.chain.size() + 2; ++i)
            good &= (c.chain.position(i + 1) - c.chain.position(i)).norm() > 0.05;
        for (std::size_t i = 0; i < c.chain.size(); ++i) {
            const Vec3d w = (c.chain.position(i) - c.chain.position(i + 1)).normalized();
            good &= std::abs(w.dot(c.chain.vertices[i].geometry.n_geometric)) > 0.1;
        }
        if (good) return c.chain;
    }
    return std::nullopt;
}

/// Turns some vertices glossy with random half-vector slopes and re-traces the chain from the
/// same first direction so that the new constraints hold.
std::optional<SpecularChain> make_glossy(const Scene& scene, const SpecularChain& chain,
                                         std::mt19937& rng, bool all) {
    std::uniform_real_distribution<double> uniform(-0.15, 0.15);
    SpecularChain c = chain;
    bool any = false;
    for (ChainVertex& v : c.vertices) {
        if (!all && rng() % 2 == 0) continue;
        v.roughness = RoughnessClass::Glossy;
        v.half_vector_slope = Vec2d(uniform(rng), uniform(rng));
        any = true;
    }
    if (!any) {
        c.vertices.front().roughness = RoughnessClass::Glossy;
        c.vertices.front().half_vector_slope = Vec2d(uniform(rng), uniform(rng));
    }
    const Vec3d last = (c.end.p - c.position(c.size())).normalized();
    const EndPlane plane = end_plane(c.end.p, c.end.on_surface() ? c.end.n_geometric : last);
    const ChainOutcome p = project_chain(scene, c, (c.position(1) - c.start.p).normalized(), plane);
    if (!p.ok()) return std::nullopt;
    SpecularChain out = p.chain;
    if (out.end.on_surface()) out.end.n_geometric = plane.normal;
    return out;
}

// --- block-tridiagonal solver ------------------------------------------------------------------

BlockTridiagonal random_system(std::size_t n, std::mt19937& rng) {
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    BlockTridiagonal s(n);
    for (std::size_t i = 0; i < n; ++i) {
        for (int r = 0; r < 2; ++r)
            for (int c = 0; c < 2; ++c) {
                s.lower[i](r, c) = i > 0 ? u(rng) : 0.0;
                s.diagonal[i](r, c) = u(rng);
                s.upper[i](r, c) = i + 1 < n ? u(rng) : 0.0;
            }
    }
    return s;
}

TEST(BlockTridiagonal, SolveAndDeterminantMatchDenseLu) {
    std::mt19937 rng(7);
    for (std::size_t n = 1; n <= 8; ++n) {
        for (int trial = 0; trial < 20; ++trial) {
            const BlockTridiagonal s = random_system(n, rng);
            std::vector<Mat2d> rhs(n);
            for (auto& r : rhs) r = Mat2d::Random();
            const auto solution = solve(s, rhs);
            ASSERT_TRUE(solution.has_value());
            const Eigen::MatrixXd dense = s.dense();
            Eigen::MatrixXd b(2 * n, 2);
            for (std::size_t i = 0; i < n; ++i)
                b.middleRows(2 * static_cast<Eigen::Index>(i), 2) = rhs[i];
            const Eigen::MatrixXd x = dense.fullPivLu().solve(b);
            for (std::size_t i = 0; i < n; ++i)
                EXPECT_LT(
                    (solution->x[i] - x.middleRows(2 * static_cast<Eigen::Index>(i), 2)).norm(),
                    1e-8 * (1.0 + x.norm()));
            EXPECT_NEAR(solution->log_abs_determinant, std::log(std::abs(dense.determinant())),
                        1e-8);
        }
    }
}

TEST(BlockTridiagonal, SingularPivotFallsBackToDenseLu) {
    // The first pivot B_0 = 0 is singular, the matrix [[0, I], [I, I]] is not.
    BlockTridiagonal s(2);
    s.diagonal[0] = Mat2d::Zero();
    s.upper[0] = Mat2d::Identity();
    s.lower[1] = Mat2d::Identity();
    s.diagonal[1] = Mat2d::Identity();
    const auto solution = solve(s, std::vector<Vec2d>{Vec2d(1, 2), Vec2d(3, 4)});
    ASSERT_TRUE(solution.has_value());
    EXPECT_TRUE(solution->used_dense_fallback);
    EXPECT_NEAR((solution->x[1] - Vec2d(1, 2)).norm(), 0.0, 1e-14);
    EXPECT_NEAR((solution->x[0] - Vec2d(2, 2)).norm(), 0.0, 1e-14);
    EXPECT_NEAR(solution->log_abs_determinant, 0.0, 1e-14);
}

TEST(BlockTridiagonal, SingularMatrixIsReportedNotSolved) {
    BlockTridiagonal s(2);
    s.diagonal[0] = Mat2d::Identity();
    s.upper[0] = Mat2d::Identity();
    s.lower[1] = Mat2d::Identity();
    s.diagonal[1] = Mat2d::Identity();  // second block row equals the first
    EXPECT_FALSE(solve(s, std::vector<Vec2d>(2, Vec2d(1, 1))).has_value());
    EXPECT_FALSE(log_abs_determinant(s).has_value());
    BlockTridiagonal nan_system(1);
    nan_system.diagonal[0](0, 0) = std::numeric_limits<double>::quiet_NaN();
    EXPECT_FALSE(solve(nan_system, std::vector<Vec2d>(1, Vec2d(1, 1))).has_value());
}

// --- constraint blocks -------------------------------------------------------------------------

void expect_blocks_match_finite_differences(const Scene& scene, const SpecularChain& chain,
                                            const std::string& label) {
    constexpr double h = 1e-5;
    const std::size_t k = chain.size();
    const Tangents start_tangents =
        tangents_around((chain.position(1) - chain.start.p).normalized());
    const Tangents last_tangents = end_tangents(chain);
    for (std::size_t i = 0; i < k; ++i) {
        const ChainVertex& v = chain.vertices[i];
        const Tangents& tp = i == 0 ? start_tangents : chain.vertices[i - 1].geometry.tangents;
        const Tangents& tn = i + 1 == k ? last_tangents : chain.vertices[i + 1].geometry.tangents;
        const Vec3d& xp = chain.position(i);
        const Vec3d& xn = chain.position(i + 2);
        const auto blocks = constraint_blocks(xp, tp, v, xn, tn, v.half_vector_slope);
        ASSERT_TRUE(blocks.has_value()) << label;
        const auto c = [&](const Vec3d& p, const SurfacePoint& g, const Vec3d& n) {
            const auto value = constraint_value(p, g, n, v.eta, v.half_vector_slope);
            EXPECT_TRUE(value.has_value());
            return value.value_or(Vec2d::Zero());
        };
        const Shape& shape = scene.shapes()[static_cast<std::size_t>(v.geometry.shape)];
        Mat2d a, b, cc;
        for (int j = 0; j < 2; ++j) {
            a.col(j) =
                (c(xp + h * tp[j], v.geometry, xn) - c(xp - h * tp[j], v.geometry, xn)) / (2 * h);
            cc.col(j) =
                (c(xp, v.geometry, xn + h * tn[j]) - c(xp, v.geometry, xn - h * tn[j])) / (2 * h);
            const auto plus = move_on_surface(shape, v.geometry, h * Vec2d::Unit(j));
            const auto minus = move_on_surface(shape, v.geometry, -h * Vec2d::Unit(j));
            ASSERT_TRUE(plus && minus);
            b.col(j) = (c(xp, *plus, xn) - c(xp, *minus, xn)) / (2 * h);
        }
        const double scale = std::max({blocks->a.norm(), blocks->b.norm(), blocks->c.norm(), 1e-3});
        EXPECT_LT((a - blocks->a).norm(), 1e-6 * scale) << label << " vertex " << i << " A\n"
                                                        << a << "\n"
                                                        << blocks->a;
        EXPECT_LT((b - blocks->b).norm(), 1e-6 * scale) << label << " vertex " << i << " B\n"
                                                        << b << "\n"
                                                        << blocks->b;
        EXPECT_LT((cc - blocks->c).norm(), 1e-6 * scale) << label << " vertex " << i << " C\n"
                                                         << cc << "\n"
                                                         << blocks->c;
    }
}

TEST(Constraints, TracedChainsSatisfyTheirConstraints) {
    std::mt19937 rng(11);
    for (const ChainKind kind : kAllKinds) {
        const Scene scene = make_scene(kind);
        for (int k = 1; k <= 6; ++k) {
            const auto chain = random_chain(scene, kind, k, rng);
            ASSERT_TRUE(chain.has_value()) << name(kind) << " k=" << k;
            for (std::size_t i = 0; i < chain->size(); ++i) {
                const ChainVertex& v = chain->vertices[i];
                const auto c = constraint_value(chain->position(i), v.geometry,
                                                chain->position(i + 2), v.eta, v.half_vector_slope);
                ASSERT_TRUE(c.has_value());
                EXPECT_LT(c->norm(), 1e-12) << name(kind) << " k=" << k << " vertex " << i;
            }
        }
    }
}

/// A triangle whose texture u runs along p2 - p0 (world y), not along its first edge, with
/// smooth vertex normals (normalised here).
TriangleMesh textured_smooth_triangle(const std::array<Vec3f, 3>& normals) {
    TriangleMesh mesh;
    mesh.positions = {{0, 0, 0}, {2, 0, 0.3f}, {0, 1, 0.1f}};
    mesh.indices = {0, 1, 2};
    mesh.uvs = {{0, 0}, {0, 1}, {1, 0}};  // u grows along p2 - p0, v along p1 - p0
    for (const Vec3f& n : normals) mesh.normals.push_back(n.normalized());
    return mesh;
}

/// The walk's constraint frame at `sp` is the shading frame the renderer evaluates BSDFs in.
void expect_walk_frame_is_the_renderers(const SurfacePoint& sp, const SurfaceInteraction& si,
                                        int i) {
    const std::optional<ConstraintFrame> frame = constraint_frame(sp);
    ASSERT_TRUE(frame.has_value());
    EXPECT_LT((frame->s - si.shading.s.cast<double>()).norm(), 1e-5) << i;
    EXPECT_LT((frame->t - si.shading.t.cast<double>()).norm(), 1e-5) << i;
}

TEST(Constraints, ShadingFrameFollowsTheTextureAndMatchesTheRenderersFrame) {
    // A triangle whose texture u runs along world y (not along its first edge, x): the shading
    // frame's s must follow u (Mitsuba 3 orients anisotropic BSDFs by the texture's dp/du), and
    // the manifold walk's frame (constraint_frame) must be the surface interaction's, or
    // anisotropic half-vector constraints would be solved in another frame than the one the
    // BSDF is evaluated in. A smooth normal tilts the frame; 20 points (seed 7).
    const Shape shape(
        textured_smooth_triangle({Vec3f(0.1f, 0, 1), Vec3f(0, 0.2f, 1), Vec3f(-0.1f, 0.1f, 1)}), 0,
        "t");
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> uniform(0.05f, 0.45f);
    for (int i = 0; i < 20; ++i) {
        const Vec2f b(uniform(rng), uniform(rng));
        SurfaceInteraction si = shape.interaction_at(0, b);
        si.shape = 0;
        const std::optional<SurfacePoint> sp = surface_point_from(shape, si);
        ASSERT_TRUE(sp.has_value());
        expect_walk_frame_is_the_renderers(*sp, si, i);
        // dp/du = p2 - p0 here: s is its part orthogonal to the shading normal.
        const Vec3f du = Vec3f(0, 1, 0.1f);
        const Vec3f want = (du - si.shading.n * si.shading.n.dot(du)).normalized();
        EXPECT_LT((si.shading.s - want).norm(), 1e-5f) << i;
    }
}

TEST(Constraints, AnInstancesSurfacePointIsTheRenderersInteraction) {
    // The same smooth-normal, textured triangle shared by an instance whose to_world mirrors
    // and stretches unevenly: the walk's surface point (world corners in double) and the
    // renderer's interaction (object space mapped to world) must describe one surface: the
    // same point, normals, shading frame and normal derivatives, at 20 points (seed 8).
    TriangleMesh mesh =
        textured_smooth_triangle({Vec3f(0.1f, 0, 1), Vec3f(0, 0.4f, 1), Vec3f(-0.3f, 0.1f, 1)});
    Mat3f linear;
    linear << -1.3f, 0.2f, 0.f, 0.1f, 0.7f, 0.3f, 0.f, -0.2f, 1.6f;
    const Shape shape(MeshInstance(std::make_shared<const Shape>(std::move(mesh), 0, "object"),
                                   linear, Vec3f(0.5f, -1.f, 2.f)),
                      0, "instance");
    ASSERT_LT(linear.determinant(), 0.f);
    std::mt19937 rng(8);
    std::uniform_real_distribution<float> uniform(0.05f, 0.45f);
    for (int i = 0; i < 20; ++i) {
        const Vec2f b(uniform(rng), uniform(rng));
        SurfaceInteraction si = shape.interaction_at(0, b);
        si.shape = 0;
        const std::optional<SurfacePoint> sp = surface_point_from(shape, si);
        ASSERT_TRUE(sp.has_value());
        EXPECT_LT((sp->p - si.p.cast<double>()).norm(), 1e-5) << i;
        EXPECT_LT((sp->n_geometric - si.n_geometric.cast<double>()).norm(), 1e-5) << i;
        EXPECT_LT((sp->n_shading - si.shading.n.cast<double>()).norm(), 1e-5) << i;
        EXPECT_LT((sp->dn_du - si.dn_du.cast<double>()).norm(), 1e-5) << i;
        EXPECT_LT((sp->dn_dv - si.dn_dv.cast<double>()).norm(), 1e-5) << i;
        expect_walk_frame_is_the_renderers(*sp, si, i);
        // The interaction's normal derivatives are those of its own normal field.
        constexpr float h = 1e-3f;
        for (int axis = 0; axis < 2; ++axis) {
            const Vec2f step = h * Vec2f::Unit(axis);
            const Vec3f fd = (shape.interaction_at(0, b + step).shading.n -
                              shape.interaction_at(0, b - step).shading.n) /
                             (2.f * h);
            EXPECT_LT((fd - (axis == 0 ? si.dn_du : si.dn_dv)).norm(), 1e-3f) << i;
        }
    }
}

TEST(Constraints, DerivativeBlocksMatchCentralFiniteDifferences) {
    std::mt19937 rng(12);
    for (const ChainKind kind : kAllKinds) {
        const Scene scene = make_scene(kind);
        for (int k = 1; k <= 6; ++k) {
            for (int trial = 0; trial < 4; ++trial) {
                const auto chain = random_chain(scene, kind, k, rng);
                ASSERT_TRUE(chain.has_value());
                const std::string label = std::string(name(kind)) + " k=" + std::to_string(k);
                expect_blocks_match_finite_differences(scene, *chain, label);
                // Off the manifold too: glossy targets and a displaced vertex, where the rotation
                // of the shading frame (dp_du and normal derivatives) enters B.
                const auto glossy = make_glossy(scene, *chain, rng, false);
                if (glossy)
                    expect_blocks_match_finite_differences(scene, *glossy, label + " glossy");
                SpecularChain displaced = *chain;
                displaced.vertices[0].half_vector_slope = Vec2d(0.2, -0.1);
                const Shape& shape =
                    scene.shapes()[static_cast<std::size_t>(displaced.vertices[0].geometry.shape)];
                const auto moved =
                    move_on_surface(shape, displaced.vertices[0].geometry, Vec2d(0.02, 0.03));
                ASSERT_TRUE(moved.has_value());
                displaced.vertices[0].geometry = *moved;
                expect_blocks_match_finite_differences(scene, displaced, label + " displaced");
            }
        }
    }
}

// --- chain Jacobians ---------------------------------------------------------------------------

/// log(dw_0/dA_end) by central differences of the forward map: direction at x_0 -> end point.
std::optional<double> finite_difference_log_solid_angle_per_area(const Scene& scene,
                                                                 const SpecularChain& chain) {
    constexpr double h = 1e-6;
    const Vec3d w0 = (chain.position(1) - chain.start.p).normalized();
    const Tangents chart = tangents_around(w0);
    const Tangents et = end_tangents(chain);
    const Vec3d n = et[0].cross(et[1]);
    EndPlane plane = end_plane(chain.end.p, n);
    plane.tangents = et;
    Mat2d j;
    for (int c = 0; c < 2; ++c) {
        const auto end_at = [&](double s) -> std::optional<Vec2d> {
            const ChainOutcome o =
                project_chain(scene, chain, (w0 + s * chart[c]).normalized(), plane);
            if (!o.ok()) return std::nullopt;
            const Vec3d d = o.chain.end.p - chain.end.p;
            return Vec2d(et[0].dot(d), et[1].dot(d));
        };
        const auto plus = end_at(h), minus = end_at(-h);
        if (!plus || !minus) return std::nullopt;
        j.col(c) = (*plus - *minus) / (2 * h);
    }
    return -std::log(std::abs(j.determinant()));
}

TEST(GeneralizedGeometry, SolidAnglePerAreaMatchesFiniteDifferencesOfTracedChains) {
    std::mt19937 rng(13);
    for (const ChainKind kind : kAllKinds) {
        const Scene scene = make_scene(kind);
        for (int k = 0; k <= 6; ++k) {
            for (int trial = 0; trial < 3; ++trial) {
                const auto chain = random_chain(
                    scene, kind, std::max(k, kind == ChainKind::GlassSphere ? 1 : 0), rng);
                ASSERT_TRUE(chain.has_value());
                const LogTerm analytic = log_solid_angle_per_area(*chain);
                ASSERT_TRUE(analytic.ok()) << to_string(analytic.failure);
                const auto fd = finite_difference_log_solid_angle_per_area(scene, *chain);
                ASSERT_TRUE(fd.has_value());
                EXPECT_NEAR(analytic.log_value, *fd, 1e-5) << name(kind) << " k=" << chain->size();
            }
        }
    }
}

TEST(GeneralizedGeometry, IsReciprocalUpToTheRatioOfIndices) {
    // Etendue eta^2 dA cos dw is conserved along a specular chain, so
    // G~(x_0 -> x_end) eta_0^2 = G~(x_end -> x_0) eta_end^2, with eta_end / eta_0 the product of
    // the relative indices eta' crossed. Only for true mirrors and interfaces: interpolated
    // shading normals break the symmetry (the mesh is left out on purpose).
    std::mt19937 rng(14);
    for (const ChainKind kind : {ChainKind::MirrorSphereInside, ChainKind::GlassSphere}) {
        const Scene scene = make_scene(kind);
        for (int k = 1; k <= 6; ++k) {
            const auto chain = random_chain(scene, kind, k, rng);
            ASSERT_TRUE(chain.has_value());
            const LogTerm forward = log_generalized_geometry_term(*chain);
            const LogTerm backward = log_generalized_geometry_term(chain->reversed());
            ASSERT_TRUE(forward.ok() && backward.ok());
            double log_eta_ratio = 0.0;
            for (const ChainVertex& v : chain->vertices) log_eta_ratio += std::log(v.eta);
            EXPECT_NEAR(forward.log_value - backward.log_value, 2.0 * log_eta_ratio, 1e-9)
                << name(kind) << " k=" << k;
        }
    }
}

TEST(GeneralizedGeometry, PlanarMirrorUnfoldsToTheOrdinaryGeometryTerm) {
    // A planar mirror: G~ = cos_0 cos_2 / (l_1 + l_2)^2 (the unfolded straight segment).
    const Scene scene = test::scene_from_xml(R"(<shape type="rectangle">
        <transform name="to_world"><scale value="10"/></transform><bsdf type="conductor"/></shape>
        <shape type="rectangle"><transform name="to_world"><scale value="10"/>
            <rotate x="1" angle="180"/><translate value="0, 0, 3"/></transform></shape>)");
    ChainEndpoint start;
    start.p = Vec3d(-1.0, 0.2, 3.0);
    start.n_geometric = Vec3d(0, 0, -1);
    const std::vector<Scatter> scatters{Scatter::Reflection};
    const ChainOutcome c =
        trace_new_chain(scene, start, Vec3d(0.5, -0.1, -1.0).normalized(), scatters, 0.0);
    ASSERT_TRUE(c.ok()) << to_string(c.failure);
    const double l = (c.chain.vertices[0].geometry.p - start.p).norm() +
                     (c.chain.end.p - c.chain.vertices[0].geometry.p).norm();
    const Vec3d w = (c.chain.vertices[0].geometry.p - start.p).normalized();
    const double expected = std::abs(w.z()) * std::abs(w.z()) / (l * l);
    const LogTerm g = log_generalized_geometry_term(c.chain);
    ASSERT_TRUE(g.ok());
    EXPECT_NEAR(g.value(), expected, 1e-12 * expected);
}

/// The 2|R| x 2|R| matrix d x_R / d sigma_R by central differences: perturb one slope, re-trace
/// from the start and walk the end back to where it was.
std::optional<double> finite_difference_log_half_vector_jacobian(const Scene& scene,
                                                                 const SpecularChain& chain,
                                                                 double h = 1e-6) {
    std::vector<std::size_t> glossy;
    for (std::size_t i = 0; i < chain.size(); ++i)
        if (chain.vertices[i].roughness == RoughnessClass::Glossy) glossy.push_back(i);
    // Central differences across a triangle edge see the kink of interpolated normals: skip
    // chains with a mesh vertex within 1e-3 (barycentric) of an edge.
    for (const ChainVertex& v : chain.vertices) {
        const Shape& shape = scene.shapes()[static_cast<std::size_t>(v.geometry.shape)];
        const Vec2d& b = v.geometry.surface_param;
        if (shape.has_triangles() && std::min({b.x(), b.y(), 1.0 - b.x() - b.y()}) < 1e-3)
            return std::nullopt;
    }
    const auto m = static_cast<Eigen::Index>(2 * glossy.size());
    Eigen::MatrixXd j(m, m);
    ManifoldConfig config;
    config.relative_tolerance = 1e-13;
    config.max_iterations = 50;
    config.check_visibility = false;
    const Vec3d last = (chain.end.p - chain.position(chain.size())).normalized();
    const EndPlane plane =
        end_plane(chain.end.p, chain.end.on_surface() ? chain.end.n_geometric : last);
    for (Eigen::Index col = 0; col < m; ++col) {
        const auto solve_with = [&](double s) -> std::optional<Eigen::VectorXd> {
            SpecularChain c = chain;
            c.vertices[glossy[static_cast<std::size_t>(col / 2)]].half_vector_slope[col % 2] += s;
            const ChainOutcome p =
                project_chain(scene, c, (c.position(1) - c.start.p).normalized(), plane);
            if (!p.ok()) return std::nullopt;
            const WalkResult r = walk(scene, p.chain, chain.end, config);
            if (!r.ok()) return std::nullopt;
            Eigen::VectorXd x(m);
            for (std::size_t g = 0; g < glossy.size(); ++g) {
                const SurfacePoint& base = chain.vertices[glossy[g]].geometry;
                const Vec3d d = r.chain.vertices[glossy[g]].geometry.p - base.p;
                x[static_cast<Eigen::Index>(2 * g)] = base.tangents[0].dot(d);
                x[static_cast<Eigen::Index>(2 * g + 1)] = base.tangents[1].dot(d);
            }
            return x;
        };
        const auto plus = solve_with(h), minus = solve_with(-h);
        if (!plus || !minus) return std::nullopt;
        j.col(col) = (*plus - *minus) / (2 * h);
    }
    return std::log(std::abs(j.determinant()));
}

TEST(GeneralizedGeometry, HalfVectorJacobianMatchesFiniteDifferences) {
    std::mt19937 rng(15);
    int checked = 0;
    for (const ChainKind kind : kAllKinds) {
        const Scene scene = make_scene(kind);
        for (int k = 1; k <= 5; ++k) {
            for (int trial = 0; trial < 3; ++trial) {
                const auto chain = random_chain(scene, kind, k, rng);
                ASSERT_TRUE(chain.has_value());
                const auto glossy = make_glossy(scene, *chain, rng, trial == 0);
                if (!glossy) continue;
                const LogTerm analytic = log_half_vector_jacobian(*glossy);
                ASSERT_TRUE(analytic.ok()) << to_string(analytic.failure);
                const auto fd = finite_difference_log_half_vector_jacobian(scene, *glossy);
                if (!fd) continue;  // near an edge, or a perturbed chain left the surface
                EXPECT_NEAR(analytic.log_value, *fd, 1e-4) << name(kind) << " k=" << k;
                ++checked;
            }
        }
    }
    EXPECT_GE(checked, 30);
}

TEST(GeneralizedGeometry, AllDeltaChainsHaveUnitHalfVectorJacobian) {
    std::mt19937 rng(16);
    const Scene scene = make_scene(ChainKind::MirrorSphereInside);
    const auto chain = random_chain(scene, ChainKind::MirrorSphereInside, 4, rng);
    ASSERT_TRUE(chain.has_value());
    const LogTerm j = log_half_vector_jacobian(*chain);
    ASSERT_TRUE(j.ok());
    EXPECT_EQ(j.log_value, 0.0);
    const LogTerm shift = log_manifold_shift_jacobian(*chain, *chain);
    ASSERT_TRUE(shift.ok());
    EXPECT_EQ(shift.log_value, 0.0);
}

TEST(GeneralizedGeometry, ShiftJacobianIsTheRatioOfHalfVectorJacobians) {
    // Composite check of the shift that keeps glossy half vectors: moving the end changes the
    // glossy positions by dx'/dsigma (dx/dsigma)^-1, whose determinant is the shift Jacobian.
    std::mt19937 rng(17);
    const Scene scene = make_scene(ChainKind::MirrorSphereInside);
    int checked = 0;
    for (int trial = 0; trial < 10 && checked < 4; ++trial) {
        const auto chain = random_chain(scene, ChainKind::MirrorSphereInside, 3, rng);
        ASSERT_TRUE(chain.has_value());
        const auto base = make_glossy(scene, *chain, rng, false);
        if (!base) continue;
        ChainEndpoint target = base->end;
        target.p += 0.05 * end_tangents(*base)[0] + 0.03 * end_tangents(*base)[1];
        if (target.on_surface()) continue;  // keep point ends: the target stays in free space
        const WalkResult offset = walk(scene, *base, target);
        if (!offset.ok()) continue;
        const LogTerm jacobian = log_manifold_shift_jacobian(*base, offset.chain);
        ASSERT_TRUE(jacobian.ok());
        const auto fd_base = finite_difference_log_half_vector_jacobian(scene, *base);
        const auto fd_offset = finite_difference_log_half_vector_jacobian(scene, offset.chain);
        if (!fd_base || !fd_offset) continue;
        EXPECT_NEAR(jacobian.log_value, *fd_offset - *fd_base, 2e-4);
        ++checked;
    }
    EXPECT_GE(checked, 2);
}

}  // namespace
}  // namespace gdmlt::manifold
