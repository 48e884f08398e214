// SPDX-License-Identifier: GPL-3.0-or-later
#include "mlt/gdmlt.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <iostream>
#include <stdexcept>

#include "core/render/render_path.h"
#include "core/scene/properties.h"
#include "mlt/gradient_sample.h"

namespace gdmlt::mlt {
namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point start) {
    return std::chrono::duration<double>(Clock::now() - start).count();
}

double luminance_of_magnitude(const Rgb& v) {
    return static_cast<double>(luminance(v.abs()));
}

/// GDMLT's target (header comment). Slots: [0, P) the primal of each pixel, [P, P + E) the
/// difference of each edge of the neighbour set, I(to) - I(from).
class GradientTarget final : public ChainTarget {
  public:
    GradientTarget(const Scene& scene, const GdmltSettings& settings,
                   const NeighbourSet& neighbours)
        : scene_(scene), settings_(settings), neighbours_(neighbours) {}

    std::size_t slot_count() const override {
        return neighbours_.pixel_count() + neighbours_.edges().size();
    }
    std::size_t density_slot_count() const override { return neighbours_.pixel_count(); }

    void evaluate(SampleStream& stream, ChainState& state, ChainCounters& counters) const override {
        const Film& film = scene_.camera().film();
        const Vec2f u = stream.next_2d();
        const float fx = u.x() * static_cast<float>(film.crop_width);
        const float fy = u.y() * static_cast<float>(film.crop_height);
        const int x = std::min(static_cast<int>(fx), film.crop_width - 1);
        const int y = std::min(static_cast<int>(fy), film.crop_height - 1);
        const std::size_t pixel = static_cast<std::size_t>(y) * film.crop_width + x;
        state.density_slot = static_cast<std::int32_t>(pixel);

        const std::span<const NeighbourLink> links = neighbours_.links(pixel);
        // Lattice pixels have at most 4 links; ADAP's may have more.
        std::array<Rgb, 8> small;
        std::vector<Rgb> large;
        std::span<Rgb> differences(small.data(), links.size());
        if (links.size() > small.size()) {
            large.resize(links.size());
            differences = large;
        }
        const GradientSample g =
            sample_gradients(scene_,
                             Vec2f(static_cast<float>(film.crop_offset_x) + fx,
                                   static_cast<float>(film.crop_offset_y) + fy),
                             stream, settings_.path, settings_.shift, links, differences,
                             counters.paths, counters.shifts);

        bool finite = is_finite(g.primal);
        double target = settings_.primal_weight * static_cast<double>(luminance(g.primal));
        for (const Rgb& d : differences) {
            finite = finite && is_finite(d);
            target += luminance_of_magnitude(d);
        }
        if (!finite || !std::isfinite(target)) {
            state.nonfinite = true;
            return;
        }
        if (!(target > 0.0)) return;
        state.target = target;
        if (!is_black(g.primal))
            state.splats.push_back({static_cast<std::uint32_t>(pixel), g.primal});
        const std::size_t edge_slots = neighbours_.pixel_count();
        for (std::size_t k = 0; k < links.size(); ++k) {
            if (is_black(differences[k])) continue;
            // A difference sampled at the edge's `to` end estimates I(from) - I(to).
            state.splats.push_back(
                {static_cast<std::uint32_t>(edge_slots + static_cast<std::size_t>(links[k].edge)),
                 links[k].from_end ? differences[k] : Rgb(-differences[k])});
        }
    }

  private:
    const Scene& scene_;
    const GdmltSettings& settings_;
    const NeighbourSet& neighbours_;
};

}  // namespace

GdmltOutput render_gdmlt(const Scene& scene, const GdmltSettings& settings,
                         const std::atomic<bool>* cancel,
                         const std::function<void(double, double)>& progress) {
    const Film& film = scene.camera().film();
    return render_gdmlt(scene, settings, NeighbourSet::lattice(film.crop_width, film.crop_height),
                        cancel, progress);
}

GdmltOutput render_gdmlt(const Scene& scene, const GdmltSettings& settings,
                         const NeighbourSet& neighbours, const std::atomic<bool>* cancel,
                         const std::function<void(double, double)>& progress) {
    const Clock::time_point start = Clock::now();
    const Film& film = scene.camera().film();
    const int width = film.crop_width, height = film.crop_height;
    if (neighbours.width() != width || neighbours.height() != height)
        throw std::invalid_argument(
            "render_gdmlt: the neighbour set is not the crop window's size");
    const auto pixels = static_cast<double>(width) * height;
    GdmltOutput out;
    GradientBuffers& b = out.buffers;

    // 1. Very direct light: camera rays only (max_depth 1 in Mitsuba's sense), cheap and never
    //    shifted.
    {
        RenderSettings direct;
        direct.spp = std::max(settings.very_direct_samples, 1);
        direct.seed = derive_stream(settings.seed, 0x7D1EC7);
        direct.path = settings.path;
        direct.path.max_depth = 1;
        const RenderOutput d = render_path(scene, direct, cancel);
        b.very_direct = d.image;
        out.stats.very_direct_s = seconds_since(start);
        out.stats.counters += d.stats.counters;
    }

    // 2. The chains.
    ChainRunnerSettings runner;
    runner.mutation = settings.mutation;
    runner.image_width = width;
    runner.image_height = height;
    runner.mutations =
        static_cast<std::uint64_t>(std::llround(settings.mutations_per_pixel * pixels));
    runner.chains =
        settings.chains > 0
            ? settings.chains
            : static_cast<int>(std::clamp<std::uint64_t>(runner.mutations / 4096, 64, 4096));
    runner.bootstrap_samples = static_cast<std::uint64_t>(settings.bootstrap_samples);
    runner.bootstrap_relative_error = settings.bootstrap_relative_error;
    if (settings.time_budget_s > 0.0) {
        runner.mutations = 0;  // the time alone decides
        runner.time_budget_s = std::max(settings.time_budget_s - seconds_since(start), 1e-3);
    }
    runner.seed = settings.seed;
    runner.kelemen_weights = settings.kelemen_weights;
    const GradientTarget target(scene, settings, neighbours);
    const ChainRunnerOutput chains = run_chains(target, runner, cancel, progress);
    const PathCounters direct_counters = out.stats.counters;
    const double very_direct_s = out.stats.very_direct_s;
    static_cast<ChainStats&>(out.stats) = chains.stats;
    out.stats.counters += direct_counters;
    out.stats.very_direct_s = very_direct_s;
    if (!(chains.stats.b > 0.0))
        std::cerr << "gdmlt: every bootstrap sample had a zero target; only very direct light "
                     "remains\n";

    // 3. Buffers: each slot's integral over primary sample space times the pixel count (a pixel
    //    covers 1/P of the image plane).
    b.primal = Image(width, height, 3);
    // No sample_count layer: reconstruction would read 1/count as the primal's variance, which
    // holds for independent samples, not for a chain's correlated, 1/f*-weighted ones (the
    // weighted control variates then gave a 2x too bright image on caustic_glass_light).
    out.sample_density = Image(width, height, 1);
    const std::size_t p_count = neighbours.pixel_count();
    for (std::size_t i = 0; i < p_count; ++i) {
        for (int c = 0; c < 3; ++c)
            b.primal.pixels[3 * i + static_cast<std::size_t>(c)] =
                static_cast<float>(chains.estimate[i][c] * pixels);
        out.sample_density.pixels[i] = static_cast<float>(chains.density[i] * pixels);
    }
    std::vector<RgbD> edge_differences(neighbours.edges().size());
    for (std::size_t e = 0; e < edge_differences.size(); ++e)
        edge_differences[e] = chains.estimate[p_count + e] * pixels;
    store_edge_differences(neighbours, edge_differences, b);
    out.stats.total_s = seconds_since(start);
    return out;
}

GdmltSettings gdmlt_settings_from_scene(const IntegratorSettings& integrator) {
    GdmltSettings s;
    s.path.max_depth = integrator.max_depth;
    s.path.rr_depth = integrator.rr_depth;
    s.path.hide_emitters = integrator.hide_emitters;
    if (integrator.desc.type != "gdmlt") return s;
    PropertyReader props(integrator.desc);
    props.mark_read({"max_depth", "rr_depth", "hide_emitters"});
    s.mutation.p_large = props.get_float("p_large", s.mutation.p_large);
    s.mutation.s1 = props.get_float("mutation_size_low", s.mutation.s1);
    s.mutation.s2 = props.get_float("mutation_size_high", s.mutation.s2);
    s.mutation.image_s2_pixels = props.get_float("image_mutation_size", s.mutation.image_s2_pixels);
    s.chains = static_cast<int>(props.get_int("chains", s.chains));
    s.bootstrap_samples = static_cast<int>(props.get_int("luminance_samples", s.bootstrap_samples));
    s.bootstrap_samples = static_cast<int>(props.get_int("bootstrap_samples", s.bootstrap_samples));
    s.bootstrap_relative_error =
        props.get_float("bootstrap_relative_error", s.bootstrap_relative_error);
    s.mutations_per_pixel = props.get_float("mutations_per_pixel", s.mutations_per_pixel);
    s.kelemen_weights = props.get_bool("kelemen_style_weights", s.kelemen_weights);
    s.primal_weight = props.get_float("primal_weight", s.primal_weight);
    s.very_direct_samples =
        static_cast<int>(props.get_int("very_direct_samples", s.very_direct_samples));
    props.check_all_read();
    validate_gdmlt_settings(s, integrator.desc.loc);
    return s;
}

void validate_gdmlt_settings(const GdmltSettings& s, const FileLoc& loc) {
    if (!(s.mutation.p_large >= 0.0 && s.mutation.p_large <= 1.0))
        throw InputError(loc, "p_large must lie in [0, 1]");
    if (!(s.mutation.s1 > 0.0 && s.mutation.s1 < s.mutation.s2 && s.mutation.s2 < 1.0))
        throw InputError(loc, "mutation sizes must satisfy 0 < s1 < s2 < 1");
    if (!(s.mutation.image_s2_pixels >= 0.0))
        throw InputError(loc, "image_mutation_size must not be negative");
    if (s.chains < 0) throw InputError(loc, "chains must not be negative");
    if (s.bootstrap_samples < 1) throw InputError(loc, "bootstrap_samples must be positive");
    if (!(s.bootstrap_relative_error >= 0.0 && s.bootstrap_relative_error < 1.0))
        throw InputError(loc, "bootstrap_relative_error must lie in [0, 1)");
    if (!(s.mutations_per_pixel > 0.0 && std::isfinite(s.mutations_per_pixel)))
        throw InputError(loc, "mutations_per_pixel must be positive");
    if (!(s.primal_weight > 0.0 && std::isfinite(s.primal_weight)))
        throw InputError(loc,
                         "primal_weight must be positive (the chain must reach every pixel "
                         "with light)");
    if (s.very_direct_samples < 1) throw InputError(loc, "very_direct_samples must be positive");
}

}  // namespace gdmlt::mlt
