// SPDX-License-Identifier: GPL-3.0-or-later
#include "manifold/manifold_walk.h"

#include <cmath>

#include "core/geometry/ray.h"
#include "manifold/block_tridiagonal.h"
#include "manifold/chain_trace.h"
#include "manifold/constraints.h"

namespace gdmlt::manifold {
namespace {

/// Normal of the plane the end moves in: symmetric in the old and new end normals and
/// orthogonal to the displacement r, so both the old and the new end lie in it.
std::optional<Vec3d> walk_plane_normal(const SpecularChain& chain, const ChainEndpoint& target,
                                       const Vec3d& r) {
    Vec3d n_old = chain.end.n_geometric, n_new = target.n_geometric;
    Vec3d m = Vec3d::Zero();
    if (chain.end.on_surface() && target.on_surface()) {
        if (n_old.dot(n_new) < 0.0) n_old = -n_old;
        m = n_old + n_new;
    } else if (chain.end.on_surface()) {
        m = n_old;
    } else if (target.on_surface()) {
        m = n_new;
    }
    const Vec3d last_segment = chain.end.p - chain.position(chain.size());
    for (const Vec3d& candidate : {m, last_segment}) {
        const Vec3d n = candidate - r * candidate.dot(r);
        const double length = n.norm();
        if (length > 1e-6 * candidate.norm() && length > 0.0) return Vec3d(n / length);
    }
    return std::nullopt;
}

bool last_segment_occluded(const Scene& scene, const SpecularChain& chain) {
    const std::size_t k = chain.size();
    const Vec3d& from = chain.position(k);
    const Vec3d n_from =
        k == 0 ? chain.start.n_geometric : chain.vertices[k - 1].geometry.n_geometric;
    const Ray ray = spawn_ray_to(from.cast<float>(), n_from.cast<float>(),
                                 chain.end.p.cast<float>(), chain.end.n_geometric.cast<float>());
    return scene.occluded(ray);
}

}  // namespace

WalkResult walk(const Scene& scene, const SpecularChain& chain, const ChainEndpoint& target,
                const ManifoldConfig& config) {
    WalkResult result;
    result.chain = chain;
    const Vec3d displacement = target.p - chain.end.p;
    const double distance0 = displacement.norm();
    const double scale =
        config.length_scale > 0.0 ? config.length_scale : chain.length() + distance0;
    if (!std::isfinite(scale) || !(scale > 0.0) || !target.p.allFinite()) {
        result.failure = WalkFailure::DegenerateChain;
        return result;
    }
    const double tolerance = config.relative_tolerance * scale;

    const auto finish = [&](SpecularChain converged, double distance) {
        result.relative_distance = distance / scale;
        const std::size_t k = converged.size();
        // A collapsed last segment (the end ran into the last vertex) has no direction.
        if (k > 0 && !((converged.end.p - converged.position(k)).norm() > tolerance)) {
            result.failure = WalkFailure::DegenerateChain;
            return;
        }
        converged.end.n_geometric = target.n_geometric;
        converged.end.shape = target.shape;
        if (k == 0) converged.end.p = target.p;
        if (config.check_visibility && last_segment_occluded(scene, converged)) {
            result.failure = WalkFailure::Occluded;
            return;
        }
        result.chain = std::move(converged);
    };

    if (chain.size() == 0 || distance0 <= tolerance) {
        finish(chain, chain.size() == 0 ? 0.0 : distance0);
        return result;
    }

    const std::optional<Vec3d> normal = walk_plane_normal(chain, target, displacement / distance0);
    if (!normal) {
        result.failure = WalkFailure::DegenerateChain;
        return result;
    }
    const EndPlane plane = end_plane(chain.end.p, *normal);
    const Vec3d goal = target.p - plane.normal * plane.normal.dot(target.p - plane.origin);

    SpecularChain current = chain;
    const BlockSolveSettings solve_settings{config.singular_threshold};
    double step = config.max_step;
    bool need_prediction = true;
    Vec2d x1_full_step = Vec2d::Zero();  // tangent displacement of x_1 for the whole distance
    WalkFailure last_rejection = WalkFailure::None;
    bool last_attempt_rejected = false;
    for (;;) {
        const Vec3d remaining = goal - current.end.p;
        const double distance = remaining.norm();
        result.relative_distance = distance / scale;
        if (distance <= tolerance) {
            finish(std::move(current), distance);
            return result;
        }
        if (result.iterations >= config.max_iterations) break;

        if (need_prediction) {
            const std::optional<ChainSystem> system = chain_system(current, plane.tangents);
            if (!system) {
                result.failure = WalkFailure::DegenerateChain;
                return result;
            }
            // Row k couples x_k to the end: move the known end displacement to the rhs.
            const Vec2d end_step(plane.tangents[0].dot(remaining),
                                 plane.tangents[1].dot(remaining));
            ChainArray<Vec2d> rhs(current.size(), Vec2d::Zero());
            rhs.back() = -system->end_coupling * end_step;
            const std::optional<BlockSolution<1>> solution =
                solve(system->matrix, as_span(rhs), solve_settings);
            if (!solution) {
                result.failure = WalkFailure::SingularMatrix;
                return result;
            }
            x1_full_step = solution->x[0];
            need_prediction = false;
        }

        const SurfacePoint& x1 = current.vertices[0].geometry;
        const Vec3d aim =
            x1.p + step * (x1_full_step.x() * x1.tangents[0] + x1_full_step.y() * x1.tangents[1]);
        const Vec3d to_aim = aim - current.start.p;
        const double aim_length = to_aim.norm();
        ++result.iterations;
        WalkFailure reason = WalkFailure::None;
        if (!(aim_length > 0.0) || !std::isfinite(aim_length)) {
            reason = WalkFailure::DegenerateChain;
        } else {
            ChainOutcome projected = project_chain(scene, current, to_aim / aim_length, plane);
            if (projected.ok()) {
                const double new_distance = (goal - projected.chain.end.p).norm();
                if (new_distance < distance) {
                    current = std::move(projected.chain);
                    ++result.accepted_steps;
                    step = std::min(config.max_step, step * config.step_grow);
                    need_prediction = true;
                    last_attempt_rejected = false;
                    continue;
                }
                reason = WalkFailure::DistanceIncreased;
            } else {
                reason = projected.failure;
            }
        }
        ++result.rejected_steps[static_cast<std::size_t>(reason)];
        last_rejection = reason;
        last_attempt_rejected = true;
        step *= config.step_shrink;
        if (step < config.min_step) break;
    }
    result.failure = last_attempt_rejected ? last_rejection : WalkFailure::NotConverged;
    result.chain = std::move(current);
    return result;
}

}  // namespace gdmlt::manifold
