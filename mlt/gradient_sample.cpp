// SPDX-License-Identifier: GPL-3.0-or-later
#include "mlt/gradient_sample.h"

#include <cmath>

namespace gdmlt::mlt {
namespace {

/// An emitter hit at the first vertex, or the environment seen through no vertex at all.
bool is_very_direct(const manifold::Contribution& c) {
    return c.kind != manifold::Contribution::Kind::NextEvent && c.vertex == 0;
}

}  // namespace

GradientSample sample_gradients(const Scene& scene, const Vec2f& film_position,
                                SampleStream& stream, const PathSamplerSettings& path_in,
                                manifold::ShiftKind shift, std::span<const NeighbourLink> links,
                                std::span<LinkEstimate> estimates, PathCounters& counters,
                                manifold::ShiftCounters& shift_counters) {
    PathSamplerSettings path = path_in;
    if (path.max_depth < 0) path.max_depth = kUnboundedDepthCap;
    const Path base = sample_camera_path(scene, film_position, stream, path, counters);
    const std::vector<manifold::Contribution> base_terms = manifold::path_contributions(
        scene, base, {}, static_cast<int>(base.vertices.size()), path.hide_emitters);

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
        const manifold::ShiftResult shifted =
            manifold::shift_path(scene, base, links[k].offset.cast<float>(), shift, shift_counters);
        const std::vector<manifold::Contribution> offset_terms =
            manifold::path_contributions(scene, shifted.offset, shifted.log_jacobian,
                                         shifted.valid_vertices, path.hide_emitters);
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
            // Both directions of the shift are strategies for the same pair of paths, and so
            // are BSDF sampling and NEE: the power heuristic over all four (Kettunen et al.
            // 2015, sec. 4.2) weights this one. The offset's pdfs are converted to the base's
            // measure by the Jacobian.
            double a2 = c.pdf * c.pdf, b2 = c.pdf_other * c.pdf_other, shifted2 = 0.0;
            Rgb f_offset = Rgb::Zero();
            if (matched) {
                const manifold::Contribution& t = offset_terms[o];
                const double jacobian = std::exp(t.log_jacobian);
                if (std::isfinite(jacobian)) {
                    shifted2 = (t.pdf * t.pdf + t.pdf_other * t.pdf_other) * jacobian * jacobian;
                    f_offset = t.f * static_cast<float>(jacobian);
                }
            }
            const auto weight_over_pdf = static_cast<float>(c.pdf / (a2 + b2 + shifted2));
            estimate.base += c.f * weight_over_pdf;
            estimate.offset += f_offset * weight_over_pdf;
        }
    }
    return out;
}

}  // namespace gdmlt::mlt
