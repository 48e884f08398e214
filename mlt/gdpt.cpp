// SPDX-License-Identifier: GPL-3.0-or-later
#include "mlt/gdpt.h"

#include <tbb/enumerable_thread_specific.h>

#include <chrono>

#include "core/render/pixel_passes.h"

namespace gdmlt::mlt {
namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point start) {
    return std::chrono::duration<double>(Clock::now() - start).count();
}

/// Per-pixel sums: primal, and the difference estimates of the samples based in this pixel
/// towards each neighbour. Combined into the lattice differences only at the end, so that no
/// two tiles ever write the same memory.
struct PixelSums {
    std::array<double, 3> primal{};
    std::array<std::array<double, 3>, 4> difference{};
    std::uint32_t samples = 0;
};

void add(std::array<double, 3>& sum, const Rgb& v) {
    for (int c = 0; c < 3; ++c) sum[static_cast<std::size_t>(c)] += static_cast<double>(v[c]);
}

}  // namespace

GradientSample sample_gradients(const Scene& scene, const Vec2f& film_position,
                                SampleStream& stream, const GdptSettings& settings,
                                const std::array<bool, 4>& neighbour_inside, PathCounters& counters,
                                manifold::ShiftCounters& shift_counters) {
    PathSamplerSettings path = settings.path;
    if (path.max_depth < 0) path.max_depth = kUnboundedDepthCap;
    const Path base = sample_camera_path(scene, film_position, stream, path, counters);
    const std::vector<manifold::Contribution> base_terms = manifold::path_contributions(
        scene, base, {}, static_cast<int>(base.vertices.size()), path.hide_emitters);

    GradientSample out;
    for (const manifold::Contribution& c : base_terms) {
        // Primal: the path tracer's estimator, MIS between BSDF sampling and NEE.
        if (c.pdf > 0.0)
            out.primal +=
                c.f * static_cast<float>(c.pdf / (c.pdf * c.pdf + c.pdf_other * c.pdf_other));
    }
    for (std::size_t i = 0; i < 4; ++i) {
        if (!neighbour_inside[i]) continue;
        out.used[i] = true;
        const manifold::ShiftResult shifted =
            manifold::shift_path(scene, base, kNeighbourOffsets[i], settings.shift, shift_counters);
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
            if (!(c.pdf > 0.0)) continue;
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
            const double weight_over_pdf = c.pdf / (a2 + b2 + shifted2);
            out.difference[i] += (f_offset - c.f) * static_cast<float>(weight_over_pdf);
        }
    }
    return out;
}

GdptOutput render_gdpt(const Scene& scene, const GdptSettings& settings,
                       const std::atomic<bool>* cancel,
                       const std::function<void(double, double)>& progress) {
    const Clock::time_point start = Clock::now();
    const Film& film = scene.camera().film();
    const int width = film.crop_width, height = film.crop_height;
    const bool timed = settings.time_budget_s > 0.0;

    std::vector<PixelSums> sums(static_cast<std::size_t>(width) * height);
    tbb::enumerable_thread_specific<PathCounters> counters;
    tbb::enumerable_thread_specific<manifold::ShiftCounters> shift_counters;
    tbb::enumerable_thread_specific<std::uint64_t> dropped(0);

    GdptOutput out;
    PixelPassSettings passes;
    passes.spp = settings.spp;
    passes.time_budget_s = settings.time_budget_s;
    passes.seed = settings.seed;
    passes.max_pass_spp = 16;
    const PixelPassResult done = run_pixel_passes(
        film, passes, cancel,
        [&](int x, int y, const Vec2f& film_position, IndependentStream& stream) {
            PixelSums& pixel = sums[static_cast<std::size_t>(y) * width + x];
            const std::array<bool, 4> inside = {x + 1 < width, x > 0, y + 1 < height, y > 0};
            const GradientSample g =
                sample_gradients(scene, film_position, stream, settings, inside, counters.local(),
                                 shift_counters.local());
            ++pixel.samples;
            bool finite = is_finite(g.primal);
            for (const Rgb& d : g.difference) finite = finite && is_finite(d);
            if (!finite) {
                ++dropped.local();
                return;
            }
            add(pixel.primal, g.primal);
            for (std::size_t i = 0; i < 4; ++i) add(pixel.difference[i], g.difference[i]);
        },
        [&](int spp_completed) {
            if (progress)
                progress(timed ? std::min(1.0, seconds_since(start) / settings.time_budget_s)
                               : static_cast<double>(spp_completed) / std::max(settings.spp, 1),
                         seconds_since(start));
        });

    // Lattice differences: dx(x, y) estimates I(x+1, y) - I(x, y) from the +x shifts of
    // pixel (x, y) and the -x shifts of pixel (x+1, y), each an estimator of its own sign.
    GradientBuffers& b = out.buffers;
    b.primal = Image(width, height, 3);
    b.dx = Image(width, height, 3);
    b.dy = Image(width, height, 3);
    b.sample_count = Image(width, height, 1);
    auto at = [&](int x, int y) -> const PixelSums& {
        return sums[static_cast<std::size_t>(y) * width + x];
    };
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            const PixelSums& p = at(x, y);
            b.sample_count(x, y) = static_cast<float>(p.samples);
            if (p.samples == 0) continue;
            const double inv = 1.0 / p.samples;
            for (int c = 0; c < 3; ++c) {
                const auto cc = static_cast<std::size_t>(c);
                b.primal(x, y, c) = static_cast<float>(p.primal[cc] * inv);
                if (x + 1 < width && at(x + 1, y).samples > 0)
                    b.dx(x, y, c) =
                        static_cast<float>(p.difference[0][cc] * inv -
                                           at(x + 1, y).difference[1][cc] / at(x + 1, y).samples);
                if (y + 1 < height && at(x, y + 1).samples > 0)
                    b.dy(x, y, c) =
                        static_cast<float>(p.difference[2][cc] * inv -
                                           at(x, y + 1).difference[3][cc] / at(x, y + 1).samples);
            }
        }
    GdptStats& s = out.stats;
    for (const PathCounters& c : counters) s.counters += c;
    for (const manifold::ShiftCounters& c : shift_counters) s.shifts += c;
    for (std::uint64_t d : dropped) s.nonfinite_dropped += d;
    for (const PixelSums& p : sums) s.samples += p.samples;
    s.spp_completed = done.spp_completed;
    s.render_s = seconds_since(start);
    s.interrupted = done.interrupted;
    return out;
}

}  // namespace gdmlt::mlt
