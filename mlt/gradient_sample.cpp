// SPDX-License-Identifier: GPL-3.0-or-later
#include "mlt/gradient_sample.h"

#include <cmath>
#include <limits>

namespace gdmlt::mlt {
namespace {

/// An emitter hit at the first vertex, or the environment seen through no vertex at all.
bool is_very_direct(const manifold::Contribution& c) {
    return c.kind != manifold::Contribution::Kind::NextEvent && c.vertex == 0;
}

/// Counts what a sampler reads, so that the camera block can be skipped to its fixed end.
class CountingStream final : public SampleStream {
  public:
    explicit CountingStream(SampleStream& inner) : inner_(inner) {}
    float next_1d() override {
        ++read_;
        return inner_.next_1d();
    }
    void skip(std::size_t count) override {
        read_ += count;
        inner_.skip(count);
    }
    std::size_t read() const { return read_; }

  private:
    SampleStream& inner_;
    std::size_t read_ = 0;
};

/// The base camera path cut after `vertex_count` vertices, its last one ending the path: the
/// subpath strategy t = vertex_count + 1 sees. Its shift then decides nothing from vertices
/// beyond the cut.
Path truncated(const Path& path, int vertex_count) {
    Path cut = path;
    cut.vertices.resize(static_cast<std::size_t>(vertex_count));
    cut.vertices.back().continued = false;
    cut.escaped = false;
    return cut;
}

/// Light tracing strategy (s, 1) of `light` written as a camera path: vertex 0 the one the
/// camera sees at the connection `c`'s film position, through the lens point `u_lens` gives, the
/// last the point on the area light, without random numbers. False where the shift cannot take it:
/// a light at infinity or with a delta position or direction, or a vertex scattered through a delta
/// lobe of a BSDF that also has others (its lobe could not be told from geometry). Both depend only
/// on what a shift keeps, so base and offset are treated alike.
bool light_path_in_camera_order(const Scene& scene, const std::vector<BdptVertex>& light, int s,
                                const BdptConnection& c, const Vec2f& u_lens, Path& path) {
    const BdptVertex& origin = light[0];
    if (origin.at_infinity || origin.delta_light || origin.emitter < 0 || s < 2) return false;
    path.vertices.clear();
    path.film_position = c.film_position;
    path.lens_sample = u_lens;
    path.camera_position = c.camera_position;
    path.camera_direction =
        (light[static_cast<std::size_t>(s - 1)].p - path.camera_position).normalized();
    path.escaped = false;
    path.replayable = false;
    Vec3f from = path.camera_position;
    for (int j = s - 1; j >= 1; --j) {
        const BdptVertex& lv = light[static_cast<std::size_t>(j)];
        PathVertex v;
        v.si = lv.si;
        const Bsdf& bsdf = scene.bsdf_of(v.si);
        v.roughness = bsdf.roughness_class();
        const Vec3f wo_world = (from - lv.p).normalized();
        v.wi_world = (light[static_cast<std::size_t>(j - 1)].p - lv.p).normalized();
        v.continued = true;
        v.transmission = v.si.n_geometric.dot(v.wi_world) * v.si.n_geometric.dot(wo_world) < 0.f;
        v.delta = j < s - 1 && lv.delta;
        const Vec3f wo = v.si.shading.to_local(wo_world), wi = v.si.shading.to_local(v.wi_world);
        if (v.delta) {
            if (v.roughness != RoughnessClass::Delta) return false;
            const BsdfSample bs = bsdf.sample(v.si.texture_point(), wo, v.transmission ? 1.f : 0.f,
                                              Vec2f(0.5f, 0.5f));
            if (!bs.valid() || !bs.delta || bs.transmission != v.transmission) return false;
            v.pdf = bs.pdf_solid_angle;
            v.f = bs.weight * bs.pdf_solid_angle;
        } else {
            v.f = bsdf.eval(v.si.texture_point(), wo, wi);
            v.pdf = bsdf.pdf(v.si.texture_point(), wo, wi);
        }
        if (!(v.pdf > 0.f) || is_black(v.f)) return false;
        path.vertices.push_back(v);
        from = lv.p;
    }
    // The light's point as a surface hit: the segment from light vertex 1 reached it. (A
    // sphere light's sampled point and the intersection differ by ~1e-3 of the distance.)
    const BdptVertex& first = light[1];
    const Vec3f d = origin.p - first.p;
    const float distance = d.norm();
    Ray ray = spawn_ray(first.p, first.n_geometric, d / distance);
    ray.t_max = distance * 1.01f;
    const SurfaceInteraction hit = scene.intersect(ray);
    if (!hit.valid() ||
        scene.shapes()[static_cast<std::size_t>(hit.shape)].emitter() != origin.emitter ||
        (hit.p - origin.p).norm() > 1e-2f * distance)
        return false;
    PathVertex end;
    end.si = hit;
    end.roughness = scene.bsdf_of(hit).roughness_class();
    path.vertices.push_back(end);
    return true;
}

/// The product of the BSDF values f (per channel) and of the densities along a camera-order
/// light path up to its vertex before the light, with its emission towards that vertex.
struct PathValue {
    Rgb f = Rgb::Ones();
    double pdf = 1.0;
};
PathValue camera_order_value(const Scene& scene, const Path& path) {
    PathValue v;
    const std::size_t n = path.vertices.size();
    for (std::size_t k = 0; k + 1 < n; ++k) {
        v.f *= path.vertices[k].f;
        v.pdf *= path.vertices[k].pdf;
    }
    const PathVertex& end = path.vertices[n - 1];
    v.f *= scene.emitted(end.si, (path.vertices[n - 2].si.p - end.si.p).normalized());
    return v;
}

/// Shifts light tracing term (s, 1) (connection `c`, weighted estimate `value`) to the
/// neighbours of the pixel it lands on (BidirectionalGradientSample). False when it stays
/// unshifted.
bool shift_light_tracing(const Scene& scene, const std::vector<BdptVertex>& light, int s,
                         const BdptConnection& c, const Vec2f& u_lens, const Rgb& value,
                         manifold::ShiftKind shift, float light_tracing_scale,
                         const NeighbourSet& neighbours, BidirectionalGradientScratch& scratch,
                         BidirectionalGradientSample& out, PathCounters& counters,
                         manifold::ShiftCounters& shift_counters) {
    Path& base = scratch.light_path;
    if (!light_path_in_camera_order(scene, light, s, c, u_lens, base)) return false;
    ++counters.bounce_rays;  // the ray that found the light's point
    const Film& film = scene.camera().film();
    const std::uint32_t pixel = crop_pixel_index(film, c.film_position);
    const std::span<const NeighbourLink> links = neighbours.links(pixel);
    BidirectionalGradientSample::LightTerm term;
    term.pixel = pixel;
    term.primal = value;
    term.first = static_cast<std::uint32_t>(out.light_estimates.size());
    term.count = static_cast<std::uint32_t>(links.size());
    const PathValue x_value = camera_order_value(scene, base);
    for (const NeighbourLink& link : links) {
        const manifold::ShiftResult shifted =
            manifold::shift_path(scene, base, link.offset.cast<float>(), shift, shift_counters);
        Rgb offset_value = Rgb::Zero();
        double rho = 0.0;
        const Path& y = shifted.offset;
        if (shifted.status == manifold::ShiftStatus::Ok &&
            y.vertices.size() == base.vertices.size()) {
            double log_j = 0.0;
            for (double l : shifted.log_jacobian) log_j += l;
            const PathValue y_value = camera_order_value(scene, y);
            // The shared light point: its forward density is the base's (same origin).
            light_subpath_from_path(scene, light[0], y, scratch.offset_light);
            const float weight = light_tracing_mis_weight(
                scene, scratch.offset_light, s,
                scene.camera().camera_end(y.camera_position, y.lens_sample), true,
                light_tracing_scale, scratch.bdpt);
            const double j = std::exp(log_j);
            rho = y_value.pdf * j / x_value.pdf;
            for (int ch = 0; ch < 3; ++ch)
                if (x_value.f[ch] > 0.f)
                    offset_value[ch] =
                        static_cast<float>(static_cast<double>(c.contribution[ch]) * weight * j *
                                           y_value.f[ch] / x_value.f[ch]);
            if (!is_finite(offset_value) || !std::isfinite(rho) || !(rho > 0.0))
                offset_value = Rgb::Zero();
        }
        const double w = is_black(offset_value) ? 1.0 : 1.0 / (1.0 + rho * rho);
        LinkEstimate e;
        e.base = value * static_cast<float>(w);
        e.offset = offset_value * static_cast<float>(w);
        out.light_estimates.push_back(e);
    }
    out.light_terms.push_back(term);
    return true;
}

}  // namespace

GradientSample sample_gradients(const Scene& scene, const Vec2f& film_position,
                                SampleStream& stream, const PathSamplerSettings& path_in,
                                manifold::ShiftKind shift, std::span<const NeighbourLink> links,
                                std::span<LinkEstimate> estimates, PathCounters& counters,
                                manifold::ShiftCounters& shift_counters) {
    PathSamplerSettings path = path_in;
    if (path.max_depth < 0) path.max_depth = kUnboundedDepthCap;
    // The paths and term lists of this call, reused by the next call on the same thread (GDPT's
    // pixels and GDMLT's chains run on many): a proposal with four links otherwise allocated
    // about fourteen vectors, and malloc/free were 8% of GDMLT's instructions. Nothing in them
    // outlives the call.
    struct Scratch {
        Path base;
        std::vector<manifold::Contribution> base_terms, offset_terms;
        manifold::ShiftResult shifted;
    };
    thread_local Scratch scratch;
    const Path& base = scratch.base;
    sample_camera_path(scene, film_position, stream, path, counters, scratch.base);
    const std::vector<manifold::Contribution>& base_terms = scratch.base_terms;
    manifold::path_contributions(scene, base, {}, static_cast<int>(base.vertices.size()),
                                 path.hide_emitters, scratch.base_terms);

    GradientSample out;
    bool shifted_terms = false;
    for (const manifold::Contribution& c : base_terms) {
        if (!(c.pdf > 0.0)) continue;
        // Primal: the path tracer's estimator, MIS between BSDF sampling and NEE.
        const Rgb value =
            c.f * static_cast<float>(c.pdf / (c.pdf * c.pdf + c.pdf_other * c.pdf_other));
        if (is_very_direct(c)) {
            out.very_direct += value;
        } else {
            out.primal += value;
            shifted_terms = true;
        }
    }
    for (std::size_t k = 0; k < links.size(); ++k) {
        LinkEstimate& estimate = estimates[k];
        estimate = LinkEstimate{};
        // Differences are sums over the base's own terms: with none (beyond very direct light)
        // there is nothing to shift. A term only the offset has is estimated from the other
        // end, where its weight is 1 because this direction cannot produce it.
        if (!shifted_terms) continue;
        const manifold::ShiftResult& shifted = scratch.shifted;
        manifold::shift_path(scene, base, links[k].offset.cast<float>(), shift, shift_counters,
                             scratch.shifted);
        const std::vector<manifold::Contribution>& offset_terms = scratch.offset_terms;
        manifold::path_contributions(scene, shifted.offset, shifted.log_jacobian,
                                     shifted.valid_vertices, path.hide_emitters,
                                     scratch.offset_terms);
        // Terms of both paths are listed in the same order (vertex, then hit before NEE);
        // pair them by (kind, vertex).
        std::size_t o = 0;
        for (const manifold::Contribution& c : base_terms) {
            while (o < offset_terms.size() &&
                   (offset_terms[o].vertex < c.vertex ||
                    (offset_terms[o].vertex == c.vertex && offset_terms[o].kind < c.kind)))
                ++o;
            const bool matched = o < offset_terms.size() && offset_terms[o].vertex == c.vertex &&
                                 offset_terms[o].kind == c.kind;
            if (!(c.pdf > 0.0) || is_very_direct(c)) continue;
            // The pair (x, y = T_s(x)) of strategy s (BSDF sampling or NEE) is produced by two
            // techniques: s from pixel i, and s from pixel j shifted back. Each path keeps its own
            // MIS weight between BSDF sampling and NEE, w_s(x) and w_s(y) (the path tracer's),
            // and the two directions share the power heuristic of p_s(x) and p_s(y) |T_s'|:
            //     D = v_s(x) [w_s(y) f(y) |T_s'| - w_s(x) f(x)] / p_s(x),
            //     v_s(x) = p_s(x)^2 / (p_s(x)^2 + (p_s(y) |T_s'|)^2).
            // Unbiased whatever the shifts of the two strategies do: per strategy the two
            // directions' weights sum to one over the pair. (A joint power heuristic over all
            // four techniques, as gradient-mts's G-PT weighs them, sums to one only where both
            // strategies shift x to the same y; where they do not, e.g. a glossy vertex lit by
            // an environment map, whose NEE offset keeps the light direction while BSDF
            // sampling's follows the half vector, it overestimated differences 1.4-1.5x.)
            const double a2 = c.pdf * c.pdf, b2 = c.pdf_other * c.pdf_other;
            const double w_base = a2 / (a2 + b2);
            double shifted2 = 0.0;
            Rgb f_offset = Rgb::Zero();
            if (matched) {
                const manifold::Contribution& t = offset_terms[o];
                const double jacobian = std::exp(t.log_jacobian);
                const double t2 = t.pdf * t.pdf, t_other2 = t.pdf_other * t.pdf_other;
                if (std::isfinite(jacobian) && t2 > 0.0) {
                    shifted2 = t2 * jacobian * jacobian;
                    f_offset = t.f * static_cast<float>(jacobian * t2 / (t2 + t_other2));
                }
            }
            const auto weight_over_pdf = static_cast<float>(c.pdf / (a2 + shifted2));
            estimate.base += c.f * static_cast<float>(w_base) * weight_over_pdf;
            estimate.offset += f_offset * weight_over_pdf;
        }
    }
    return out;
}

void sample_bidirectional_gradients(const Scene& scene, const Vec2f& film_position,
                                    SampleStream& stream, const PathSamplerSettings& path_in,
                                    manifold::ShiftKind shift, std::span<const NeighbourLink> links,
                                    std::span<LinkEstimate> estimates,
                                    const NeighbourSet* neighbours,
                                    BidirectionalGradientScratch& scratch,
                                    BidirectionalGradientSample& out, PathCounters& counters,
                                    manifold::ShiftCounters& shift_counters,
                                    const BidirectionalGradientOptions& options) {
    PathSamplerSettings path = path_in;
    if (path.max_depth < 0) path.max_depth = kUnboundedDepthCap;
    path.rr_depth = std::numeric_limits<int>::max();
    path.min_depth = 1;
    const int max_depth = path.max_depth;

    // 1. The two subpaths, in fixed blocks of numbers.
    CountingStream counting(stream);
    const Path base = sample_camera_path(scene, film_position, counting, path, counters);
    // The block: the thin lens's two numbers (when the camera has a lens), then the vertices'.
    const std::size_t lens_numbers = scene.camera().needs_lens_sample() ? 2 : 0;
    stream.skip(lens_numbers +
                static_cast<std::size_t>(kDimensionsPerBounce) *
                    static_cast<std::size_t>(max_depth) -
                counting.read());
    std::vector<BdptVertex>& light = scratch.bdpt.light;
    sample_light_subpath(scene, stream, max_depth, std::numeric_limits<int>::max(), light,
                         counters);
    camera_subpath_from_path(scene, base, static_cast<int>(base.vertices.size()),
                             scratch.base_camera);

    // 2. The base's strategies. Paths of one segment (very direct light) are left out.
    out.primal = Rgb::Zero();
    out.light_splats.clear();
    out.light_terms.clear();
    out.light_estimates.clear();
    out.nonfinite = 0;
    scratch.terms.clear();
    BdptConnectionInput in;
    in.light = &light;
    in.light_tracing_scale = options.light_tracing_scale;
    in.u_lens = base.lens_sample;  // light tracing connects to the base's lens point
    const auto n_camera = static_cast<int>(scratch.base_camera.size());
    const auto n_light = static_cast<int>(light.size());
    // The camera prefix of strategy t ends at path vertex t - 2; s = 1 uses its light sample.
    const auto set_light_sample = [&](const Path& p, int t, BdptConnectionInput& input) {
        input.light_sample = nullptr;
        input.light_sample_visible = false;
        const auto v = static_cast<std::size_t>(t - 2);
        if (input.s == 1 && v < p.vertices.size()) {
            input.light_sample = &p.vertices[v].light;
            input.light_sample_visible = p.vertices[v].light_visible;
        }
    };
    static const EmitterSample kNoLight{};
    for (int t = 1; t <= n_camera; ++t) {
        for (int s = 0; s <= n_light; ++s) {
            const int segments = s + t - 1;
            if (segments < 2 || segments > max_depth) continue;
            if (t == 1 && options.without_light_tracing) continue;
            in.camera = &scratch.base_camera;
            in.s = s;
            in.t = t;
            set_light_sample(base, t, in);
            // s = 1 without a sample at that vertex (delta BSDF, no light): no strategy.
            if (s == 1 && t >= 2 && !in.light_sample) in.light_sample = &kNoLight;
            const BdptConnection c = connect_bdpt(scene, in, scratch.bdpt, counters);
            if (is_black(c.contribution)) continue;
            const Rgb value = c.contribution * c.weight;
            if (!is_finite(value)) {
                ++out.nonfinite;
                continue;
            }
            if (is_black(value)) continue;
            if (t == 1) {
                if (!neighbours || !shift_light_tracing(scene, light, s, c, in.u_lens, value, shift,
                                                        options.light_tracing_scale, *neighbours,
                                                        scratch, out, counters, shift_counters))
                    out.light_splats.push_back({c.film_position, value});
            } else {
                out.primal += value;
                scratch.terms.push_back({s, t, value});
            }
        }
    }

    // 3. Per link, the offsets of every base term.
    for (std::size_t k = 0; k < links.size(); ++k) {
        LinkEstimate& estimate = estimates[k];
        estimate = LinkEstimate{};
        if (scratch.terms.empty()) continue;
        const Vec2f offset = links[k].offset.cast<float>();
        const manifold::ShiftResult full =
            manifold::shift_path(scene, base, offset, shift, shift_counters);
        camera_subpath_from_path(scene, full.offset, full.valid_vertices, scratch.offset_camera);
        // A shift of a cut path, for the prefixes whose shift could depend on what follows
        // them (below); computed once per prefix length.
        int cut_t = -1;
        manifold::ShiftResult cut_shift;
        std::vector<BdptVertex> cut_camera;
        for (const BidirectionalGradientScratch::Term& term : scratch.terms) {
            const int t = term.t;
            const auto last = static_cast<std::size_t>(t - 2);  // the prefix's last path vertex
            // The full path's shift decides the prefix's vertices from the prefix alone, except
            // where its last vertex is specular or left through a delta lobe (a smooth coat):
            // there the unidirectional shift looks at what follows. Shift the cut path then.
            const bool needs_cut = last < base.vertices.size() &&
                                   (base.vertices[last].roughness == RoughnessClass::Delta ||
                                    (base.vertices[last].continued && base.vertices[last].delta));
            const manifold::ShiftResult* shifted = &full;
            const std::vector<BdptVertex>* offset_camera = &scratch.offset_camera;
            if (needs_cut) {
                if (cut_t != t) {
                    cut_shift = manifold::shift_path(scene, truncated(base, t - 1), offset, shift,
                                                     shift_counters);
                    camera_subpath_from_path(scene, cut_shift.offset, cut_shift.valid_vertices,
                                             cut_camera);
                    cut_t = t;
                }
                shifted = &cut_shift;
                offset_camera = &cut_camera;
            }
            Rgb offset_value = Rgb::Zero();
            double rho = 0.0;
            if (static_cast<int>(offset_camera->size()) >= t) {
                // p_st(y) |T'| / p_st(x): the camera directions leaving path vertices 0 .. t - 3
                // (the pinhole's is a film translation: densities equal, Jacobian 1).
                double log_rho = 0.0;
                for (std::size_t j = 0; j + 3 <= static_cast<std::size_t>(t); ++j) {
                    const PathVertex& xv = base.vertices[j];
                    const PathVertex& yv = shifted->offset.vertices[j];
                    log_rho += std::log(static_cast<double>(yv.pdf)) -
                               std::log(static_cast<double>(xv.pdf)) +
                               (j < shifted->log_jacobian.size() ? shifted->log_jacobian[j] : 0.0);
                }
                rho = std::exp(log_rho);
                in.camera = offset_camera;
                in.s = term.s;
                in.t = t;
                set_light_sample(shifted->offset, t, in);
                if (term.s == 1 && !in.light_sample) in.light_sample = &kNoLight;
                const BdptConnection c = connect_bdpt(scene, in, scratch.bdpt, counters);
                if (!is_black(c.contribution) && std::isfinite(rho) && rho > 0.0) {
                    offset_value = c.contribution * static_cast<float>(c.weight * rho);
                    if (!is_finite(offset_value)) offset_value = Rgb::Zero();
                }
            }
            // Power heuristic between the shift's two directions; a side that contributes
            // nothing is estimated from the other alone.
            const double weight = is_black(offset_value) ? 1.0 : 1.0 / (1.0 + rho * rho);
            estimate.base += term.value * static_cast<float>(weight);
            estimate.offset += offset_value * static_cast<float>(weight);
        }
    }
}

}  // namespace gdmlt::mlt
