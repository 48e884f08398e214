// SPDX-License-Identifier: GPL-3.0-or-later
#include "manifold/shift.h"

#include <cmath>
#include <utility>

#include "manifold/chain_trace.h"
#include "manifold/generalized_geometry.h"
#include "manifold/manifold_walk.h"
#include "manifold/specular_chain.h"

namespace gdmlt::manifold {

const char* to_string(ShiftStatus status) {
    switch (status) {
        case ShiftStatus::Ok:
            return "ok";
        case ShiftStatus::Escaped:
            return "escaped";
        case ShiftStatus::Occluded:
            return "occluded";
        case ShiftStatus::ClassificationChanged:
            return "classification_changed";
        case ShiftStatus::LobeChanged:
            return "lobe_changed";
        case ShiftStatus::TotalInternalReflection:
            return "total_internal_reflection";
        case ShiftStatus::ManifoldNotConverged:
            return "manifold_not_converged";
        case ShiftStatus::ManifoldDistanceIncreased:
            return "manifold_distance_increased";
        case ShiftStatus::ManifoldOccluded:
            return "manifold_occluded";
        case ShiftStatus::ManifoldLeftManifold:
            return "manifold_left_manifold";
        case ShiftStatus::ManifoldTotalInternalReflection:
            return "manifold_total_internal_reflection";
        case ShiftStatus::ManifoldSingularMatrix:
            return "manifold_singular_matrix";
        case ShiftStatus::ManifoldDegenerateChain:
            return "manifold_degenerate_chain";
        case ShiftStatus::ManifoldNotReversible:
            return "manifold_not_reversible";
        case ShiftStatus::NotReplayable:
            return "not_replayable";
        case ShiftStatus::Count:
            break;
    }
    return "?";
}

const char* to_string(ShiftKind kind) {
    switch (kind) {
        case ShiftKind::Auto:
            return "auto";
        case ShiftKind::Reconnect:
            return "reconnect";
        case ShiftKind::HalfVector:
            return "halfvector";
        case ShiftKind::Replay:
            return "replay";
    }
    return "?";
}

ShiftCounters& ShiftCounters::operator+=(const ShiftCounters& o) {
    for (std::size_t i = 0; i < by_status.size(); ++i) by_status[i] += o.by_status[i];
    shifts += o.shifts;
    reconnections += o.reconnections;
    half_vector_steps += o.half_vector_steps;
    replay_steps += o.replay_steps;
    manifold_walks += o.manifold_walks;
    manifold_shifts += o.manifold_shifts;
    manifold_iterations += o.manifold_iterations;
    return *this;
}

namespace {

Vec3f previous_position(const Path& path, std::size_t k) {
    return k == 0 ? path.camera_position : path.vertices[k - 1].si.p;
}

/// The base's next-event sample seen from the offset vertex `y`: the same point on the light
/// (or the same direction for an infinite light), so the light vertex's Jacobian is the ratio
/// of the area-to-solid-angle factors (1 for directions and for point lights).
void shift_light_sample(const Scene& scene, const PathVertex& x, PathVertex& y) {
    y.light = EmitterSample{};
    y.light_visible = false;
    y.log_light_jacobian = 0.0;
    const EmitterSample& lx = x.light;
    if (!lx.valid() || y.roughness == RoughnessClass::Delta) return;
    EmitterSample ly = lx;
    if (std::isinf(lx.distance)) {
        // Environment direction: unchanged.
    } else {
        const Vec3f d = lx.p - y.si.p;
        const float dist2 = d.squaredNorm();
        if (!(dist2 > 0.f)) return;
        ly.distance = std::sqrt(dist2);
        ly.wi = d / ly.distance;
        if (lx.delta) {
            // A light at a point: its intensity towards y over the squared distance (a spot's
            // falloff and a projector's or textured spot's image depend on the direction); the
            // pdf is the discrete choice.
            ly.radiance = scene.delta_position_radiance(lx.emitter, -ly.wi, dist2);
        } else {
            const float cos_x = -lx.n_geometric.dot(lx.wi);
            const float cos_y = -lx.n_geometric.dot(ly.wi);
            if (!(cos_y > 0.f) || !(cos_x > 0.f)) return;  // the light faces away from y
            const double ratio = (static_cast<double>(cos_y) * lx.distance * lx.distance) /
                                 (static_cast<double>(cos_x) * dist2);
            ly.pdf_solid_angle = static_cast<float>(lx.pdf_solid_angle / ratio);
            y.log_light_jacobian = std::log(ratio);
        }
    }
    y.light = ly;
    const Ray shadow = std::isinf(ly.distance)
                           ? spawn_ray(y.si.p, y.si.n_geometric, ly.wi)
                           : spawn_ray_to(y.si.p, y.si.n_geometric, ly.p, ly.n_geometric);
    y.light_visible = !scene.occluded(shadow);
}

/// f and pdf of leaving offset vertex `y` (reached from `from`) towards `to_world` through its
/// non-delta lobes; false when the direction is on the wrong side of the geometry.
bool evaluate_continuation(const Scene& scene, PathVertex& y, const Vec3f& from,
                           const Vec3f& to_world) {
    const Bsdf& bsdf = scene.bsdf_of(y.si);
    const Vec3f wo_world = (from - y.si.p).normalized();
    const Vec3f wo = y.si.shading.to_local(wo_world);
    const Vec3f wi = y.si.shading.to_local(to_world);
    y.wi_world = to_world;
    y.f = bsdf.eval(y.si.texture_point(), wo, wi);
    y.pdf = bsdf.pdf(y.si.texture_point(), wo, wi);
    y.delta = false;
    y.continued = true;
    const float side = y.si.n_geometric.dot(to_world) * y.si.n_geometric.dot(wo_world);
    y.transmission = side < 0.f;
    return y.pdf > 0.f && std::isfinite(y.pdf) && is_finite(y.f);
}

ShiftStatus manifold_status(WalkFailure failure) {
    switch (failure) {
        case WalkFailure::None:
            return ShiftStatus::Ok;
        case WalkFailure::NotConverged:
            return ShiftStatus::ManifoldNotConverged;
        case WalkFailure::DistanceIncreased:
            return ShiftStatus::ManifoldDistanceIncreased;
        case WalkFailure::Occluded:
            return ShiftStatus::ManifoldOccluded;
        case WalkFailure::LeftManifold:
            return ShiftStatus::ManifoldLeftManifold;
        case WalkFailure::TotalInternalReflection:
            return ShiftStatus::ManifoldTotalInternalReflection;
        case WalkFailure::SingularMatrix:
            return ShiftStatus::ManifoldSingularMatrix;
        case WalkFailure::DegenerateChain:
            return ShiftStatus::ManifoldDegenerateChain;
    }
    return ShiftStatus::ManifoldDegenerateChain;
}

/// The walk back from the offset chain must return every base chain vertex within this
/// fraction of the chain's length (a different solution of the same constraints is a
/// different map, and the inverse shift would not be its inverse).
constexpr double kReversibilityTolerance = 1e-6;

/// The light-side end of the delta chain that follows base vertex k, when the manifold shift
/// applies there: x_k is connectable, x_{k+1} .. x_{m-1} are delta surfaces left through delta
/// lobes, and x_m is a diffuse surface that is connectable or ends the path. 0 otherwise.
/// Depends only on the classes of the path's vertices, which the shift preserves, so the
/// inverse shift takes the same decision.
std::size_t manifold_chain_end(const Path& base, std::size_t k) {
    const std::size_t n = base.vertices.size();
    if (!base.vertices[k].connectable() || k + 2 >= n) return 0;
    std::size_t m = k + 1;
    while (m < n && base.vertices[m].roughness == RoughnessClass::Delta &&
           base.vertices[m].continued && base.vertices[m].delta)
        ++m;
    if (m == k + 1 || m >= n) return 0;
    const PathVertex& end = base.vertices[m];
    if (end.roughness != RoughnessClass::Diffuse || !(end.connectable() || !end.continued))
        return 0;
    return m;
}

/// The manifold shift at base vertex k with chain end m (manifold_chain_end): the offset's
/// vertex y_k (the last of `y`, already traced) is joined to the base's x_m through the
/// base's delta chain, walked so that every vertex keeps its (delta: normal) half vector;
/// x_m and everything after it is shared. Appends the offset's vertices k+1 .. n-1 and their
/// log Jacobians, sets log_jacobian[k].
///
/// Jacobian of the direction leaving y_k per direction leaving x_k: both map to the same
/// area element at the pinned x_m, so
///     dw_y / dw_x = (dw_y / dA_m) / (dw_x / dA_m),
/// each factor the solid angle per area through the chain (the generalized geometry term
/// without the cosine at the moving end; with an empty chain this is the reconnection's
/// cos'/d'^2 / (cos/d^2)). Delta vertices contribute no Jacobian (Dirac measure), and the
/// directions leaving x_m and beyond are shared (Jacobian 1).
ShiftStatus manifold_shift(const Scene& scene, const Path& base, std::size_t k, std::size_t m,
                           Path& y, std::vector<double>& log_jacobian, ShiftCounters& counters) {
    const std::size_t n = base.vertices.size();
    const PathVertex& xk = base.vertices[k];
    const PathVertex& xm = base.vertices[m];
    PathVertex& yk = y.vertices.back();

    // The base chain, oriented from the pinned x_m (walk start) to x_k (the moving end).
    ChainArray<SurfaceInteraction> specular;
    for (std::size_t j = m - 1; j > k; --j) specular.push_back(base.vertices[j].si);
    const ChainOutcome built =
        build_chain(scene, endpoint_at(scene, xm.si), as_span(specular), endpoint_at(scene, xk.si));
    if (!built.ok()) return manifold_status(built.failure);
    // The float vertices satisfy the half-vector constraints only to float precision, which
    // the chain amplifies (1e-4 of the scene at the end of a glass sphere's chain). Make the
    // base chain exact in double first: trace it from x_m through x_{m-1} and walk its end back
    // onto x_k. Both shift directions start from such exact chains, so the reversibility check
    // below can be tight.
    const ManifoldConfig config{};
    const SpecularChain& raw = built.chain;
    const ChainOutcome traced =
        project_chain(scene, raw, (raw.vertices[0].geometry.p - raw.start.p).normalized(),
                      end_plane(raw.end.p, raw.end.n_geometric));
    if (!traced.ok()) return manifold_status(traced.failure);
    const WalkResult polished = walk(scene, traced.chain, raw.end, config);
    counters.manifold_iterations += static_cast<std::uint64_t>(polished.iterations);
    if (!polished.ok()) return manifold_status(polished.failure);
    const SpecularChain& chain = polished.chain;
    const LogTerm base_term = log_solid_angle_per_area(chain.reversed());
    if (!base_term.ok()) return manifold_status(base_term.failure);

    ++counters.manifold_walks;
    const WalkResult there = walk(scene, chain, endpoint_at(scene, yk.si), config);
    counters.manifold_iterations += static_cast<std::uint64_t>(there.iterations);
    if (!there.ok()) return manifold_status(there.failure);
    const SpecularChain& walked = there.chain;

    // Invertibility: the walk from the offset chain back to x_k must find the base's chain.
    const WalkResult back = walk(scene, walked, endpoint_at(scene, xk.si), config);
    counters.manifold_iterations += static_cast<std::uint64_t>(back.iterations);
    if (!back.ok()) return ShiftStatus::ManifoldNotReversible;
    const double tolerance = kReversibilityTolerance * chain.length();
    for (std::size_t i = 0; i < chain.size(); ++i)
        if ((back.chain.vertices[i].geometry.p - chain.vertices[i].geometry.p).norm() > tolerance)
            return ShiftStatus::ManifoldNotReversible;

    const LogTerm offset_term = log_solid_angle_per_area(walked.reversed());
    if (!offset_term.ok()) return manifold_status(offset_term.failure);

    // Offset vertex j (k < j < m) is walked vertex m - 1 - j; positions in double.
    auto position = [&](std::size_t j) -> Vec3d {
        if (j == k) return walked.end.p;
        if (j == m) return walked.start.p;
        return walked.vertices[m - 1 - j].geometry.p;
    };
    const Vec3f from = previous_position(y, k);
    const Vec3f dir_k = (position(k + 1) - position(k)).normalized().cast<float>();
    if (!evaluate_continuation(scene, yk, from, dir_k) || yk.transmission)
        return ShiftStatus::ManifoldOccluded;

    std::vector<PathVertex> added;
    added.reserve(m - k - 1);
    for (std::size_t j = k + 1; j < m; ++j) {
        const ChainVertex& cv = walked.vertices[m - 1 - j];
        const PathVertex& xj = base.vertices[j];
        PathVertex v;
        v.si = to_interaction(scene.shapes()[static_cast<std::size_t>(cv.geometry.shape)],
                              cv.geometry);
        const Bsdf& bsdf = scene.bsdf_of(v.si);
        v.roughness = bsdf.roughness_class();
        if (v.roughness != xj.roughness) return ShiftStatus::ClassificationChanged;
        const Vec3d p = position(j);
        const Vec3f wo_world = (position(j - 1) - p).normalized().cast<float>();
        v.wi_world = (position(j + 1) - p).normalized().cast<float>();
        // The walked chain fixes reflection versus refraction; the lobe's weight and
        // probability are the offset's own (its Fresnel term at its own angle).
        const BsdfSample bs = bsdf.sample(v.si.texture_point(), v.si.shading.to_local(wo_world),
                                          cv.reflection ? 0.f : 1.f, xj.u_direction);
        if (!bs.valid() || !bs.delta || bs.transmission == cv.reflection)
            return cv.reflection ? ShiftStatus::LobeChanged
                                 : ShiftStatus::ManifoldTotalInternalReflection;
        v.continued = true;
        v.u_lobe = xj.u_lobe;
        v.u_direction = xj.u_direction;
        v.pdf = bs.pdf_solid_angle;
        v.f = bs.weight * bs.pdf_solid_angle;
        v.delta = true;
        v.transmission = bs.transmission;
        shift_light_sample(scene, xj, v);
        added.push_back(v);
    }
    for (PathVertex& v : added) {
        y.vertices.push_back(v);
        log_jacobian.push_back(0.0);
    }
    // From x_m on the paths coincide; x_m's continuation sees a new incoming direction.
    // (Appended in place: a vertex is ~300 bytes, and going through a temporary copied each
    // twice, 1% of GDMLT's instructions on cbox_glass_sphere.)
    const Vec3f last_walked = y.vertices.back().si.p;
    for (std::size_t j = m; j < n; ++j) {
        PathVertex& shared = y.vertices.emplace_back(base.vertices[j]);
        if (j == m && shared.continued)
            evaluate_continuation(scene, shared, last_walked, shared.wi_world);
        log_jacobian.push_back(0.0);
    }
    y.escaped = base.escaped;
    y.escape_direction = base.escape_direction;
    log_jacobian[k] = offset_term.log_value - base_term.log_value;
    ++counters.manifold_shifts;
    return ShiftStatus::Ok;
}

/// |d(direction)/d(half vector)| in solid angle for the direction `wi` leaving a microfacet
/// interface with normal h, incident `wo` (Walter et al. 2007, eqs. 14 and 16): 4 |wo.h| for
/// reflection; (n_o wo.h + n_t wi.h)^2 / (n_t^2 |wi.h|) for refraction.
double direction_per_half_vector(const Vec3f& wo, const Vec3f& wi, const Vec3f& h,
                                 bool transmission, float n_o, float n_t) {
    if (!transmission) return 4.0 * std::abs(static_cast<double>(wo.dot(h)));
    const double denominator =
        static_cast<double>(n_o) * wo.dot(h) + static_cast<double>(n_t) * wi.dot(h);
    return denominator * denominator /
           (static_cast<double>(n_t) * n_t * std::abs(static_cast<double>(wi.dot(h))));
}

/// The offset's continuation at a glossy vertex keeping the base's half vector (local frame).
/// Fills y's f, pdf and direction and the log Jacobian of the map w_x -> w_y.
ShiftStatus copy_half_vector(const Scene& scene, const Path& base, std::size_t k, PathVertex& y,
                             const Vec3f& from, double* log_jacobian) {
    const PathVertex& x = base.vertices[k];
    const Vec3f wo_x = x.si.shading.to_local((previous_position(base, k) - x.si.p).normalized());
    const Vec3f wi_x = x.si.shading.to_local(x.wi_world);
    const Vec3f wo_y_world = (from - y.si.p).normalized();
    const Vec3f wo_y = y.si.shading.to_local(wo_y_world);
    if (wo_x.z() * wo_y.z() <= 0.f) return ShiftStatus::ClassificationChanged;
    // Indices on the incident (wo) and transmitted sides; 1 and 1 for reflection.
    float n_o = 1.f, n_t = 1.f;
    if (x.transmission) {
        const Bsdf& bsdf = scene.bsdf_of(x.si);
        // Composites (mask, blend) hide which component refracted: no half vector to copy.
        const auto* model =
            bsdf.is_composite() ? nullptr : std::get_if<RoughDielectricBsdf>(&bsdf.front());
        if (!model) return ShiftStatus::LobeChanged;
        (wo_x.z() > 0.f ? n_t : n_o) = model->eta;
    }
    Vec3f h = x.transmission ? Vec3f(n_o * wo_x + n_t * wi_x) : Vec3f(wo_x + wi_x);
    const float length = h.norm();
    if (!(length > 1e-12f)) return ShiftStatus::LobeChanged;
    h /= length;
    if (h.z() < 0.f) h = -h;

    Vec3f wi_y;
    const float c = wo_y.dot(h);
    if (!x.transmission) {
        wi_y = 2.f * c * h - wo_y;
    } else {
        const float eta = n_o / n_t;
        const float k2 = 1.f - eta * eta * (1.f - c * c);
        if (k2 < 0.f) return ShiftStatus::TotalInternalReflection;
        wi_y = -eta * wo_y + (eta * c - std::copysign(std::sqrt(k2), c)) * h;
        wi_y.normalize();
    }
    const Bsdf& bsdf = scene.bsdf_of(y.si);
    y.continued = true;
    y.delta = false;
    y.transmission = x.transmission;
    y.u_lobe = x.u_lobe;
    y.u_direction = x.u_direction;
    y.wi_world = y.si.shading.to_world(wi_y);
    y.f = bsdf.eval(y.si.texture_point(), wo_y, wi_y);
    y.pdf = bsdf.pdf(y.si.texture_point(), wo_y, wi_y);
    const float side = y.si.n_geometric.dot(y.wi_world) * y.si.n_geometric.dot(wo_y_world);
    if ((x.transmission ? side > 0.f : side < 0.f) || !(y.pdf > 0.f) || !is_finite(y.f))
        return ShiftStatus::LobeChanged;
    const double j = direction_per_half_vector(wo_y, wi_y, h, x.transmission, n_o, n_t) /
                     direction_per_half_vector(wo_x, wi_x, h, x.transmission, n_o, n_t);
    if (!(j > 0.0) || !std::isfinite(j)) return ShiftStatus::LobeChanged;
    *log_jacobian = std::log(j);
    return ShiftStatus::Ok;
}

}  // namespace

ShiftResult shift_path(const Scene& scene, const Path& base, const Vec2f& film_offset,
                       ShiftKind kind, ShiftCounters& counters) {
    ShiftResult result;
    shift_path(scene, base, film_offset, kind, counters, result);
    return result;
}

void shift_path(const Scene& scene, const Path& base, const Vec2f& film_offset, ShiftKind kind,
                ShiftCounters& counters, ShiftResult& result) {
    ++counters.shifts;
    {
        // A fresh result that keeps the storage of the one passed in.
        std::vector<double> log_jacobian = std::move(result.log_jacobian);
        log_jacobian.clear();
        reset_keeping_capacity(result.offset);
        Path offset = std::move(result.offset);
        result = ShiftResult{};
        result.offset = std::move(offset);
        result.log_jacobian = std::move(log_jacobian);
    }
    Path& y = result.offset;
    y.film_position = base.film_position + film_offset;
    y.lens_sample = base.lens_sample;
    Ray ray = scene.camera().generate_ray(y.film_position, y.lens_sample);
    y.camera_position = ray.origin;
    y.camera_direction = ray.direction;

    auto finish = [&](ShiftStatus status, int valid) {
        result.status = status;
        result.valid_vertices = valid;
        ++counters.by_status[static_cast<std::size_t>(status)];
    };

    const std::size_t n = base.vertices.size();
    // The offset has at most the base's vertices: allocate once (see sample_camera_path).
    y.vertices.reserve(n);
    result.log_jacobian.reserve(n);
    for (std::size_t k = 0;; ++k) {
        // Trace the offset's ray to its vertex k (k = 0: the shifted primary ray).
        const SurfaceInteraction si = scene.intersect(ray);
        const bool base_has_vertex = k < n;
        if (!si.valid()) {
            if (!base_has_vertex && base.escaped) {
                y.escaped = true;
                y.escape_direction = ray.direction;
                return finish(ShiftStatus::Ok, static_cast<int>(k));
            }
            return finish(ShiftStatus::Escaped, static_cast<int>(k));
        }
        if (!base_has_vertex)
            return finish(ShiftStatus::ClassificationChanged, static_cast<int>(k));
        const PathVertex& x = base.vertices[k];
        PathVertex v;
        v.si = si;
        v.roughness = scene.bsdf_of(si).roughness_class();
        // The inverse shift takes the same decisions only if both paths have the same
        // classes vertex by vertex (and the same emitter status).
        const bool x_emits = scene.shapes()[static_cast<std::size_t>(x.si.shape)].emitter() >= 0;
        const bool y_emits = scene.shapes()[static_cast<std::size_t>(si.shape)].emitter() >= 0;
        if (v.roughness != x.roughness || x_emits != y_emits)
            return finish(ShiftStatus::ClassificationChanged, static_cast<int>(k));
        shift_light_sample(scene, x, v);
        y.vertices.push_back(v);
        result.log_jacobian.push_back(0.0);
        PathVertex& yk = y.vertices.back();
        if (!x.continued) return finish(ShiftStatus::Ok, static_cast<int>(k + 1));

        const Vec3f from = previous_position(y, k);
        const bool next_exists = k + 1 < n;
        const bool reconnects = kind == ShiftKind::Auto || kind == ShiftKind::Reconnect;
        const bool can_reconnect =
            reconnects && x.connectable() && yk.roughness == RoughnessClass::Diffuse &&
            next_exists &&
            (base.vertices[k + 1].connectable() || !base.vertices[k + 1].continued) &&
            base.vertices[k + 1].roughness == RoughnessClass::Diffuse;
        if (can_reconnect) {
            // Reconnection (Lehtinen et al. 2013, sec. 5.2): y_k connects to the base's x_{k+1};
            // the direction Jacobian is the ratio of the area-to-solid-angle factors at x_{k+1}.
            const PathVertex& next = base.vertices[k + 1];
            const Vec3f d = next.si.p - yk.si.p;
            const float dist2 = d.squaredNorm();
            const Vec3f dx = next.si.p - x.si.p;
            if (!(dist2 > 0.f)) return finish(ShiftStatus::Occluded, static_cast<int>(k + 1));
            const Vec3f dir = d / std::sqrt(dist2);
            const float cos_y = std::abs(next.si.n_geometric.dot(dir));
            const float cos_x = std::abs(next.si.n_geometric.dot(dx.normalized()));
            if (!(cos_y > 0.f) || !(cos_x > 0.f) || !evaluate_continuation(scene, yk, from, dir))
                return finish(ShiftStatus::Occluded, static_cast<int>(k + 1));
            if (scene.occluded(
                    spawn_ray_to(yk.si.p, yk.si.n_geometric, next.si.p, next.si.n_geometric)))
                return finish(ShiftStatus::Occluded, static_cast<int>(k + 1));
            result.log_jacobian[k] = std::log((static_cast<double>(cos_y) * dx.squaredNorm()) /
                                              (static_cast<double>(cos_x) * dist2));
            // From x_{k+1} on the paths coincide; only x_{k+1}'s own continuation sees a
            // different incoming direction.
            // (yk's position is read first: appending may move the vertices.)
            const Vec3f yk_p = yk.si.p;
            for (std::size_t j = k + 1; j < n; ++j) {
                PathVertex& shared = y.vertices.emplace_back(base.vertices[j]);
                if (j == k + 1 && shared.continued)
                    evaluate_continuation(scene, shared, yk_p, shared.wi_world);
                result.log_jacobian.push_back(0.0);
            }
            y.escaped = base.escaped;
            y.escape_direction = base.escape_direction;
            result.reconnected_at = static_cast<int>(k + 1);
            ++counters.reconnections;
            return finish(ShiftStatus::Ok, static_cast<int>(n));
        }

        // Manifold shift (Auto only, and only where the scene has specular surfaces).
        if (kind == ShiftKind::Auto && scene.features().specular_chains_possible &&
            yk.roughness == RoughnessClass::Diffuse) {
            if (const std::size_t m = manifold_chain_end(base, k); m > 0) {
                const ShiftStatus status =
                    manifold_shift(scene, base, k, m, y, result.log_jacobian, counters);
                if (status != ShiftStatus::Ok) return finish(status, static_cast<int>(k + 1));
                result.reconnected_at = static_cast<int>(m);
                result.manifold_chain_at = static_cast<int>(k + 1);
                return finish(ShiftStatus::Ok, static_cast<int>(n));
            }
        }

        // Half-vector copy through a glossy vertex (Kettunen et al. 2015, sec. 4.1; Lehtinen et
        // al. 2013, sec. 5.2): the offset keeps the base's half vector in its own shading frame.
        if ((kind == ShiftKind::Auto || kind == ShiftKind::HalfVector) && !x.delta &&
            x.roughness == RoughnessClass::Glossy) {
            double log_j = 0.0;
            const ShiftStatus status = copy_half_vector(scene, base, k, yk, from, &log_j);
            if (status != ShiftStatus::Ok) return finish(status, static_cast<int>(k + 1));
            result.log_jacobian[k] = log_j;
            ++counters.half_vector_steps;
            ray = spawn_ray(yk.si.p, yk.si.n_geometric, yk.wi_world);
            continue;
        }

        // Half-vector copy / replay: sample the offset's BSDF with the base's random numbers.
        // For a delta lobe this copies the half vector (mirror or refraction of the offset's own
        // incident direction; Jacobian 1 for the Dirac measure); for a non-delta lobe the map of
        // random numbers to directions gives the Jacobian p_x(w_x) / p_y(w_y).
        // A path without numbers (a light subpath) keeps a delta vertex's lobe by its kind
        // (mirror or refraction, as the manifold walk does); anything else would be a replay.
        if (!base.replayable && !(x.delta && x.roughness == RoughnessClass::Delta))
            return finish(ShiftStatus::NotReplayable, static_cast<int>(k + 1));
        const float u_lobe = base.replayable ? x.u_lobe : (x.transmission ? 1.f : 0.f);
        const Bsdf& bsdf = scene.bsdf_of(yk.si);
        const Vec3f wo_world = (from - yk.si.p).normalized();
        const BsdfSample bs = bsdf.sample(yk.si.texture_point(), yk.si.shading.to_local(wo_world),
                                          u_lobe, x.u_direction);
        if (!bs.valid()) {
            return finish(
                x.transmission ? ShiftStatus::TotalInternalReflection : ShiftStatus::LobeChanged,
                static_cast<int>(k + 1));
        }
        if (bs.delta != x.delta || bs.transmission != x.transmission) {
            const bool tir = x.transmission && !bs.transmission && x.delta;
            return finish(tir ? ShiftStatus::TotalInternalReflection : ShiftStatus::LobeChanged,
                          static_cast<int>(k + 1));
        }
        yk.continued = true;
        yk.u_lobe = x.u_lobe;  // the inverse shift replays the same numbers
        yk.u_direction = x.u_direction;
        yk.wi_world = yk.si.shading.to_world(bs.wi);
        yk.pdf = bs.pdf_solid_angle;
        yk.f = bs.weight * bs.pdf_solid_angle;
        yk.delta = bs.delta;
        yk.transmission = bs.transmission;
        const float side = yk.si.n_geometric.dot(yk.wi_world) * yk.si.n_geometric.dot(wo_world);
        if (bs.transmission ? side > 0.f : side < 0.f)
            return finish(ShiftStatus::LobeChanged, static_cast<int>(k + 1));
        result.log_jacobian[k] =
            bs.delta
                ? 0.0
                : std::log(static_cast<double>(x.pdf) / static_cast<double>(bs.pdf_solid_angle));
        (bs.delta ? counters.half_vector_steps : counters.replay_steps) += 1;
        ray = spawn_ray(yk.si.p, yk.si.n_geometric, yk.wi_world);
    }
}

std::vector<Contribution> path_contributions(const Scene& scene, const Path& path,
                                             const std::vector<double>& log_jacobian,
                                             int valid_vertices, bool hide_emitters) {
    std::vector<Contribution> out;
    path_contributions(scene, path, log_jacobian, valid_vertices, hide_emitters, out);
    return out;
}

void path_contributions(const Scene& scene, const Path& path,
                        const std::vector<double>& log_jacobian, int valid_vertices,
                        bool hide_emitters, std::vector<Contribution>& out) {
    out.clear();
    // At most an emitter hit and a next-event term per vertex, and an escape.
    out.reserve(2 * path.vertices.size() + 1);
    Rgb f_prefix = Rgb::Ones();  // product of f over the directions leaving vertices < k
    double pdf_prefix = 1.0;     // same for the pdfs (the camera direction: 1)
    double log_j_prefix = 0.0;
    const auto count = std::min<std::size_t>(path.vertices.size(),
                                             static_cast<std::size_t>(std::max(valid_vertices, 0)));
    for (std::size_t k = 0; k < count; ++k) {
        const PathVertex& v = path.vertices[k];
        const Vec3f prev = previous_position(path, k);
        const Vec3f wo_world = (prev - v.si.p).normalized();

        // Emitter hit at v (reached by BSDF sampling from k-1, or directly visible). Listed
        // even when it emits nothing towards wo: its shifted counterpart may, and the
        // gradient needs both terms with their pdfs.
        const bool on_emitter = scene.shapes()[static_cast<std::size_t>(v.si.shape)].emitter() >= 0;
        if (on_emitter && !(k == 0 && hide_emitters)) {
            const Rgb le = scene.emitted(v.si, wo_world);
            {
                Contribution c;
                c.kind = Contribution::Kind::EmitterHit;
                c.vertex = static_cast<int>(k);
                c.f = f_prefix * le;
                c.pdf = pdf_prefix;
                if (k > 0 && !path.vertices[k - 1].delta) {
                    const PathVertex& p = path.vertices[k - 1];
                    c.pdf_other = pdf_prefix / p.pdf * scene.pdf_emitter_solid_angle(p.si.p, v.si);
                }
                c.log_jacobian = log_j_prefix;
                out.push_back(c);
            }
        }
        // Next-event estimation from v.
        if (v.light.valid()) {
            const Bsdf& bsdf = scene.bsdf_of(v.si);
            const Vec3f wo = v.si.shading.to_local(wo_world);
            const Vec3f wi = v.si.shading.to_local(v.light.wi);
            Contribution c;
            c.kind = Contribution::Kind::NextEvent;
            c.vertex = static_cast<int>(k);
            c.f = v.light_visible
                      ? Rgb(f_prefix * bsdf.eval(v.si.texture_point(), wo, wi) * v.light.radiance)
                      : Rgb(Rgb::Zero());
            c.pdf = pdf_prefix * v.light.pdf_solid_angle;
            c.pdf_other = v.light.delta ? 0.0 : pdf_prefix * bsdf.pdf(v.si.texture_point(), wo, wi);
            c.log_jacobian = log_j_prefix + (k < log_jacobian.size() ? v.log_light_jacobian : 0.0);
            out.push_back(c);
        }
        if (!v.continued) break;
        f_prefix *= v.f;
        pdf_prefix *= v.pdf;
        if (k < log_jacobian.size()) log_j_prefix += log_jacobian[k];
        if (!(pdf_prefix > 0.0) || is_black(f_prefix)) break;
        // Escape to the environment after the last vertex.
        if (k + 1 == path.vertices.size() && path.escaped && scene.has_environment()) {
            Contribution c;
            c.kind = Contribution::Kind::Escape;
            c.vertex = static_cast<int>(k + 1);
            const Scene::EnvironmentValue env = scene.environment_with_pdf(path.escape_direction);
            c.f = f_prefix * env.radiance;
            c.pdf = pdf_prefix;
            if (!v.delta) c.pdf_other = pdf_prefix / v.pdf * env.pdf_solid_angle;
            c.log_jacobian = log_j_prefix;
            out.push_back(c);
        }
    }
    if (path.vertices.empty() && path.escaped && scene.has_environment() && !hide_emitters &&
        valid_vertices >= 0) {
        Contribution c;
        c.kind = Contribution::Kind::Escape;
        c.vertex = 0;
        c.f = scene.environment(path.escape_direction);
        c.pdf = 1.0;
        out.push_back(c);
    }
}

}  // namespace gdmlt::manifold
