// SPDX-License-Identifier: GPL-3.0-or-later
#include "mlt/gdmlt.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <iostream>
#include <stdexcept>

#include "core/image/combine_buffers.h"
#include "core/math/stopwatch.h"
#include "core/render/render_path.h"
#include "core/render/render_ptracer.h"
#include "core/sampling/rng.h"
#include "core/sampling/sample_stream.h"
#include "core/scene/properties.h"
#include "mlt/gdpt.h"
#include "mlt/gradient_sample.h"

namespace gdmlt::mlt {
namespace {

/// The light tracing pass runs (GdmltSettings::light_tracing_pass).
bool lt_pass_enabled(const GdmltSettings& s) {
    return s.bidirectional && !s.shift_light_tracing && s.light_tracing_pass;
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
        return light_slot(0) + (settings_.bidirectional ? neighbours_.pixel_count() : 0);
    }
    /// Bidirectional: after the edges, the light tracing image of each pixel.
    std::size_t light_slot(std::size_t pixel) const {
        return neighbours_.pixel_count() + neighbours_.edges().size() + pixel;
    }
    std::size_t density_slot_count() const override { return neighbours_.pixel_count(); }

    void evaluate(SampleStream& stream, ChainState& state, ChainCounters& counters) const override {
        const FilmSample where = film_sample(scene_.camera().film(), stream);
        const std::size_t pixel = where.pixel;
        state.density_slot = static_cast<std::int32_t>(pixel);

        const std::span<const NeighbourLink> links = neighbours_.links(pixel);
        // Lattice pixels have at most 4 links; ADAP's may have more.
        std::array<LinkEstimate, 8> small;
        std::vector<LinkEstimate> large;
        std::span<LinkEstimate> estimates(small.data(), links.size());
        if (links.size() > small.size()) {
            large.resize(links.size());
            estimates = large;
        }
        GradientSample g;
        // Evaluations run concurrently on the chains' threads: one scratch per thread.
        thread_local BidirectionalGradientSample bidirectional;
        bidirectional.light_splats.clear();
        bidirectional.light_terms.clear();
        bool finite = true;
        if (settings_.bidirectional) {
            thread_local BidirectionalGradientScratch scratch;
            sample_bidirectional_gradients(
                scene_, where.film_position, stream, settings_.path, settings_.shift, links,
                estimates, settings_.shift_light_tracing ? &neighbours_ : nullptr, scratch,
                bidirectional, counters.paths, counters.shifts,
                {static_cast<float>(settings_.light_tracing_mis), lt_pass_enabled(settings_)});
            g.primal = bidirectional.primal;
            finite = bidirectional.nonfinite == 0;
        } else {
            g = sample_gradients(scene_, where.film_position, stream, settings_.path,
                                 settings_.shift, links, estimates, counters.paths,
                                 counters.shifts);
        }

        finite = finite && is_finite(g.primal);
        double target = settings_.primal_weight * static_cast<double>(luminance(g.primal));
        const double link_scale = difference_scale(pixel);
        for (const LinkEstimate& e : estimates) {
            finite = finite && is_finite(e.base) && is_finite(e.offset);
            target += link_scale * luminance_of_magnitude(e.difference());
        }
        // Light tracing, per light path: a slot's integral over primary sample space times the
        // pixel count is its pixel value, so each of its records is divided by that count.
        const Film& film = scene_.camera().film();
        const float pixels =
            static_cast<float>(film.crop_width) * static_cast<float>(film.crop_height);
        for (BdptSample::Splat& splat : bidirectional.light_splats) {
            splat.value /= pixels;
            finite = finite && is_finite(splat.value);
            target += settings_.primal_weight * static_cast<double>(luminance(splat.value));
        }
        for (BidirectionalGradientSample::LightTerm& term : bidirectional.light_terms) {
            term.primal /= pixels;
            finite = finite && is_finite(term.primal);
            target += settings_.primal_weight * static_cast<double>(luminance(term.primal));
            const double term_scale = difference_scale(term.pixel);
            for (std::uint32_t k = 0; k < term.count; ++k) {
                LinkEstimate& e = bidirectional.light_estimates[term.first + k];
                e.base /= pixels;
                e.offset /= pixels;
                finite = finite && is_finite(e.base) && is_finite(e.offset);
                target += term_scale * luminance_of_magnitude(e.difference());
            }
        }
        if (!finite || !std::isfinite(target)) {
            state.nonfinite = true;
            return;
        }
        if (!(target > 0.0)) return;
        state.target = target;
        const auto slot = [](std::size_t index) { return static_cast<std::uint32_t>(index); };
        if (settings_.primal_from_offsets && !links.empty()) {
            // G-PT's primal (mlt/gradient_sample.h, LinkEstimate): pixel i's share of each pair
            // here, and each neighbour j's share, estimated by the offset, there; 1/n per pair.
            // f* > 0 covers them: with C = 0 every base and offset half is 0 too.
            Rgb own = Rgb::Zero();
            for (const LinkEstimate& e : estimates) own += e.base;
            own /= static_cast<float>(links.size());
            if (!is_black(own)) state.splats.push_back({slot(pixel), own});
            for (std::size_t k = 0; k < links.size(); ++k) {
                const GradientEdge& edge =
                    neighbours_.edges()[static_cast<std::size_t>(links[k].edge)];
                const auto other =
                    static_cast<std::size_t>(links[k].from_end ? edge.to : edge.from);
                const Rgb share =
                    estimates[k].offset / static_cast<float>(neighbours_.links(other).size());
                if (!is_black(share)) state.splats.push_back({slot(other), share});
            }
        } else if (!is_black(g.primal)) {
            state.splats.push_back({slot(pixel), g.primal});
        }
        const std::size_t edge_slots = neighbours_.pixel_count();
        for (std::size_t k = 0; k < links.size(); ++k) {
            const Rgb d = estimates[k].difference();
            if (is_black(d)) continue;
            // A difference sampled at the edge's `to` end estimates I(from) - I(to).
            state.splats.push_back({slot(edge_slots + static_cast<std::size_t>(links[k].edge)),
                                    links[k].from_end ? d : Rgb(-d)});
        }
        for (const BdptSample::Splat& splat : bidirectional.light_splats)
            state.splats.push_back(
                {slot(light_slot(crop_pixel_index(film, splat.film_position))), splat.value});
        for (const BidirectionalGradientSample::LightTerm& term : bidirectional.light_terms) {
            state.splats.push_back({slot(term.pixel), term.primal});
            const std::span<const NeighbourLink> term_links = neighbours_.links(term.pixel);
            for (std::uint32_t k = 0; k < term.count; ++k) {
                const Rgb d = bidirectional.light_estimates[term.first + k].difference();
                if (is_black(d)) continue;
                state.splats.push_back(
                    {slot(edge_slots + static_cast<std::size_t>(term_links[k].edge)),
                     term_links[k].from_end ? d : Rgb(-d)});
            }
        }
    }

  private:
    /// The weight of a pixel's differences in f*: its lattice link count over its link count
    /// (1 on the lattice). A pixel whose shifts fail has |D_k| = C on every link, so an
    /// unscaled sum weighs it by its link count: ADAP's pixels with 8-12 links along image
    /// edges got a target several times their lattice neighbours', the chains lingered there
    /// and rejected their way out (longer rejection streaks, lower acceptance, measured on
    /// cbox_glass_sphere). Scaled, the graph decides which differences a pixel samples, not
    /// how much of the chains' time it draws.
    double difference_scale(std::size_t pixel) const {
        if (!settings_.normalise_link_count) return 1.0;
        const auto links = static_cast<double>(neighbours_.links(pixel).size());
        if (links == 0.0) return 1.0;
        const int width = neighbours_.width(), height = neighbours_.height();
        const int x = static_cast<int>(pixel % static_cast<std::size_t>(width));
        const int y = static_cast<int>(pixel / static_cast<std::size_t>(width));
        const int lattice = (x > 0) + (x + 1 < width) + (y > 0) + (y + 1 < height);
        return static_cast<double>(lattice) / links;
    }

    const Scene& scene_;
    const GdmltSettings& settings_;
    const NeighbourSet& neighbours_;
};

/// Stream families of the passes beside the main chains (the main chains keep the settings'
/// seed, so that `gdpt_share 0` renders what GDMLT rendered before the split existed).
constexpr std::uint64_t kGdptStreams = 0x6D97;
constexpr std::uint64_t kPilotChainStreams = 0xC9170;

/// What a part of the budget cost: wall time and rays traced.
struct PartCost {
    double seconds = 0.0;
    std::uint64_t rays = 0;
};

/// The chains' estimate as buffers: each slot's integral over primary sample space times the
/// pixel count (a pixel covers 1/P of the image plane), its variance times the count's square.
struct ChainPart {
    GradientBuffers buffers;  // primal, differences and their variances (no very direct)
    Image sample_density;
    Image light;  // bidirectional: the light tracing strategies' image (unshifted)
    ChainStats stats;
};

ChainPart run_chains_into_buffers(const Scene& scene, const GdmltSettings& settings,
                                  const NeighbourSet& neighbours, const ChainRunnerSettings& runner,
                                  const std::atomic<bool>* cancel,
                                  const std::function<void(double, double)>& progress) {
    const int width = neighbours.width(), height = neighbours.height();
    const auto pixels = static_cast<double>(width) * height;
    const GradientTarget target(scene, settings, neighbours);
    const ChainRunnerOutput chains = run_chains(target, runner, cancel, progress);
    ChainPart part;
    part.stats = chains.stats;
    GradientBuffers& b = part.buffers;
    b.primal = Image(width, height, 3);
    // No sample_count layer: reconstruction would read 1/count as the primal's variance, which
    // holds for independent samples, not for a chain's correlated, 1/f*-weighted ones (the
    // weighted control variates then gave a 2x too bright image on caustic_glass_light).
    // The variances come from batch means over the chains' rounds instead (run_chains).
    part.sample_density = Image(width, height, 1);
    const std::size_t p_count = neighbours.pixel_count();
    const bool with_variance = !chains.variance.empty();
    const double variance_scale = pixels * pixels;
    if (with_variance) b.primal_variance = Image(width, height, 1);
    for (std::size_t i = 0; i < p_count; ++i) {
        for (int c = 0; c < 3; ++c)
            b.primal.pixels[3 * i + static_cast<std::size_t>(c)] =
                static_cast<float>(chains.estimate[i][c] * pixels);
        part.sample_density.pixels[i] = static_cast<float>(chains.density[i] * pixels);
        if (with_variance)
            b.primal_variance.pixels[i] = static_cast<float>(chains.variance[i] * variance_scale);
    }
    std::vector<RgbD> edge_differences(neighbours.edges().size());
    std::vector<double> edge_variances(with_variance ? edge_differences.size() : 0);
    for (std::size_t e = 0; e < edge_differences.size(); ++e) {
        edge_differences[e] = chains.estimate[p_count + e] * pixels;
        if (with_variance) edge_variances[e] = chains.variance[p_count + e] * variance_scale;
    }
    store_edge_differences(neighbours, edge_differences, b, edge_variances);
    part.light = Image(width, height, 3);
    if (settings.bidirectional) {
        const std::size_t light_slots = p_count + neighbours.edges().size();
        for (std::size_t i = 0; i < p_count; ++i)
            for (int c = 0; c < 3; ++c)
                part.light.pixels[3 * i + static_cast<std::size_t>(c)] =
                    static_cast<float>(chains.estimate[light_slots + i][c] * pixels);
    }
    return part;
}

/// The noise of two estimates of the same layers on a common scale: the sum over slots of
/// each one's variance (leave-one-out window means, as the combination weighs them) over
/// (I^2 + 0.01), I the channel mean of the first estimate's primal at the slot (the relMSE
/// denominator of bench/metrics.py); edges weigh 1, primals kGdmltReconstructAlpha^2, the
/// weight of each kind of row in the screened Poisson solve. Slots where either is unknown
/// (+inf) are left out.
struct NoiseMeasure {
    double first = 0.0, second = 0.0;
    std::uint64_t slots = 0;
};
NoiseMeasure measure_noise(const GradientBuffers& a, const GradientBuffers& b, int radius) {
    NoiseMeasure m;
    const int w = a.primal.width, h = a.primal.height;
    std::vector<double> level(a.primal.pixel_count());
    for (std::size_t i = 0; i < level.size(); ++i)
        level[i] =
            (a.primal.pixels[3 * i] + a.primal.pixels[3 * i + 1] + a.primal.pixels[3 * i + 2]) /
            3.0;
    const auto add = [&](const Image& va, const Image& vb, double row_weight, int dx, int dy) {
        if (va.pixels.empty() || vb.pixels.empty()) return;
        const std::vector<double> sa = leave_one_out_window_mean(va, radius);
        const std::vector<double> sb = leave_one_out_window_mean(vb, radius);
        for (int y = 0; y + dy < h; ++y)
            for (int x = 0; x + dx < w; ++x) {
                const std::size_t i = static_cast<std::size_t>(y) * w + x;
                if (!std::isfinite(sa[i]) || !std::isfinite(sb[i])) continue;
                const double l =
                    0.5 * (level[i] + level[i + static_cast<std::size_t>(dy * w + dx)]);
                const double scale = row_weight / (l * l + 0.01);
                m.first += sa[i] * scale;
                m.second += sb[i] * scale;
                ++m.slots;
            }
    };
    add(a.primal_variance, b.primal_variance, kGdmltReconstructAlpha * kGdmltReconstructAlpha, 0,
        0);
    add(a.dx_variance, b.dx_variance, 1.0, 1, 0);
    add(a.dy_variance, b.dy_variance, 1.0, 0, 1);
    return m;
}

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
        out.stats.nonfinite_dropped += d.stats.nonfinite_samples_dropped;
    }
    // 1b. Bidirectional: light tracing's share from a pass of its own, weighted against the
    //     strategies the chain samples. Its subpaths must be the chain's (same depth cap, no
    //     roulette: sample_bidirectional_gradients) so that the weights of a path's strategies
    //     sum to one across the two estimators.
    const bool light_tracing_pass = lt_pass_enabled(settings);
    if (light_tracing_pass) {
        const Clock::time_point pass_start = Clock::now();
        RenderSettings lt;
        lt.seed = derive_stream(settings.seed, 0x11A55);
        lt.path = settings.path;
        if (lt.path.max_depth < 0) lt.path.max_depth = kUnboundedDepthCap;
        lt.path.rr_depth = std::numeric_limits<int>::max();
        lt.path.min_depth = 2;  // one segment is the very direct pass's
        if (settings.time_budget_s > 0.0) {
            lt.spp = std::numeric_limits<int>::max();
            lt.time_budget_s = std::max(
                settings.light_tracing_share * (settings.time_budget_s - seconds_since(start)),
                1e-3);
        } else {
            lt.spp = std::max(settings.light_tracing_spp, 1);
        }
        PtracerWeights weights;
        weights.bdpt_mis = true;
        weights.light_tracing_scale = static_cast<float>(settings.light_tracing_mis);
        const RenderOutput l = render_ptracer(scene, lt, cancel, {}, weights);
        for (std::size_t i = 0; i < b.very_direct.pixels.size(); ++i)
            b.very_direct.pixels[i] += l.image.pixels[i];
        out.stats.counters += l.stats.counters;
        out.stats.nonfinite_dropped += l.stats.nonfinite_samples_dropped;
        out.stats.light_paths = l.stats.samples;
        out.stats.light_tracing_s = seconds_since(pass_start);
    }

    // 2. The gradient-domain estimates: the chains, and (unidirectional) GDPT passes, combined
    //    by inverse variance (GdmltSettings::gdpt_share).
    const bool timed = settings.time_budget_s > 0.0;
    const auto remaining_s = [&] {
        return std::max(settings.time_budget_s - seconds_since(start), 1e-3);
    };
    BudgetSplit& split = out.stats.split;
    split.mode = settings.gdpt_share < 0.0 ? "auto" : "share";
    double gdpt_share = settings.gdpt_share;
    if (settings.bidirectional && gdpt_share != 0.0) {
        // GDPT's samples are unidirectional: its primal holds light tracing's share too, which
        // the bidirectional chain leaves to its very direct layer, so the two do not estimate
        // the same layers.
        gdpt_share = 0.0;
        split.reason = "bidirectional: GDPT's layers are not the chain's";
    }
    std::vector<GradientBuffers> parts;
    std::vector<std::string> part_names;
    std::vector<std::pair<Image, Image>> gdpt_very_direct;  // (image, sample counts) per pass
    ChainPart chain_part;
    bool chains_ran = false;
    const auto run_gdpt_part = [&](double share_of_remaining, double spp, std::uint64_t salt) {
        GdptSettings g;
        g.seed = derive_stream(settings.seed, kGdptStreams, salt);
        g.path = settings.path;
        g.shift = settings.shift;
        if (timed) {
            g.spp = std::numeric_limits<int>::max();
            g.time_budget_s = share_of_remaining * remaining_s();
        } else {
            g.spp = std::max(2, static_cast<int>(std::llround(spp)));
        }
        const Clock::time_point pass_start = Clock::now();
        GdptOutput pass = render_gdpt(scene, g, neighbours, cancel);
        const double pass_s = seconds_since(pass_start);
        split.gdpt_s += pass_s;
        split.gdpt_samples += pass.stats.samples;
        out.stats.counters += pass.stats.counters;
        out.stats.shifts += pass.stats.shifts;
        out.stats.nonfinite_dropped += pass.stats.nonfinite_dropped;
        gdpt_very_direct.emplace_back(std::move(pass.buffers.very_direct),
                                      std::move(pass.buffers.sample_count));
        pass.buffers.sample_count = Image();
        PartCost cost{pass_s, pass.stats.counters.rays()};
        parts.push_back(std::move(pass.buffers));
        part_names.push_back("gdpt");
        return cost;
    };
    const auto run_chain_part = [&](double share_of_remaining, double mutations_per_pixel,
                                    std::uint64_t seed, bool main) {
        GdmltSettings c = settings;
        c.seed = seed;
        c.mutations_per_pixel = mutations_per_pixel;
        // One chain per 1024 proposals (4096 bidirectional), at least 64
        // (GdmltSettings::chains), counted from the whole budget (mutations_per_pixel).
        ChainRunnerSettings runner =
            runner_settings(settings, width, height, settings.bidirectional ? 4096 : 1024, 64,
                            timed ? share_of_remaining * remaining_s() : 0.0);
        if (!timed)
            runner.mutations = static_cast<std::uint64_t>(
                std::llround(std::max(mutations_per_pixel, 0.0) * pixels));
        runner.seed = seed;
        runner.bootstrap_relative_error = settings.bootstrap_relative_error;
        runner.batch_variance = true;
        const Clock::time_point pass_start = Clock::now();
        ChainPart part = run_chains_into_buffers(scene, c, neighbours, runner, cancel,
                                                 main ? progress : nullptr);
        const double pass_s = seconds_since(pass_start);
        PartCost cost{pass_s, part.stats.counters.rays()};
        if (chains_ran) {
            // Two chain runs: the stats of the main run, the work of both.
            part.stats.counters += chain_part.stats.counters;
            part.stats.shifts += chain_part.stats.shifts;
        }
        chains_ran = true;
        parts.push_back(std::move(part.buffers));
        part_names.push_back(main ? "chains" : "chains (pilot)");
        chain_part = std::move(part);
        return cost;
    };

    if (gdpt_share == 0.0) {
        split.decision = "chains";
        if (split.reason.empty()) split.reason = "gdpt_share 0";
        run_chain_part(1.0, settings.mutations_per_pixel, settings.seed, true);
    } else if (gdpt_share > 0.0) {
        split.decision = gdpt_share >= 1.0 ? "gdpt" : "both";
        split.reason = "gdpt_share given";
        run_gdpt_part(gdpt_share, gdpt_share * settings.mutations_per_pixel, 0);
        if (gdpt_share < 1.0 && !(cancel && cancel->load()))
            run_chain_part(1.0, (1.0 - gdpt_share) * settings.mutations_per_pixel, settings.seed,
                           true);
    } else {
        // Auto: a pilot of each, then the rest of the budget to the one that gave less noise
        // for its cost (time with a time budget, else rays traced: deterministic).
        const double pilot = settings.pilot_share;
        const PartCost gdpt_cost = run_gdpt_part(pilot, pilot * settings.mutations_per_pixel, 0);
        const PartCost chain_cost = run_chain_part(
            timed ? pilot / (1.0 - pilot) : 1.0, pilot * settings.mutations_per_pixel,
            derive_stream(settings.seed, kPilotChainStreams), false);
        const NoiseMeasure noise = measure_noise(parts[0], parts[1], settings.combine_radius);
        split.gdpt_noise = noise.first;
        split.chain_noise = noise.second;
        split.slots_compared = noise.slots;
        const double gdpt_spent = timed ? gdpt_cost.seconds : static_cast<double>(gdpt_cost.rays);
        const double chain_spent =
            timed ? chain_cost.seconds : static_cast<double>(chain_cost.rays);
        // Efficiency 1 / (noise x cost): the noise of a pass falls as 1 / its cost.
        split.gdpt_efficiency = 1.0 / (noise.first * gdpt_spent);
        split.chain_efficiency = 1.0 / (noise.second * chain_spent);
        split.cost_unit = timed ? "s" : "rays";
        const bool chains_win = split.chain_efficiency > split.gdpt_efficiency;
        split.decision = chains_win ? "chains" : "gdpt";
        split.reason = chains_win ? "the chains' pilot had the lower noise for its cost"
                                  : "GDPT's pilot had the lower noise for its cost";
        if (!(cancel && cancel->load())) {
            const double rest = std::max(1.0 - 2.0 * pilot, 0.0) * settings.mutations_per_pixel;
            if (chains_win)
                run_chain_part(1.0, rest, settings.seed, true);
            else
                run_gdpt_part(1.0, rest, 1);
        }
    }

    // Chain statistics (of the main run); the passes' work was added to the counters above.
    const PathCounters pass_counters = out.stats.counters;
    const manifold::ShiftCounters pass_shifts = out.stats.shifts;
    const std::uint64_t pass_nonfinite = out.stats.nonfinite_dropped;
    if (chains_ran) static_cast<ChainStats&>(out.stats) = chain_part.stats;
    out.stats.counters += pass_counters;
    out.stats.shifts += pass_shifts;
    out.stats.nonfinite_dropped += pass_nonfinite;
    if (chains_ran && !(chain_part.stats.b > 0.0))
        std::cerr << "gdmlt: every bootstrap sample had a zero target; only very direct light "
                     "remains\n";
    out.sample_density =
        chains_ran ? std::move(chain_part.sample_density) : Image(width, height, 1, 1.0f);

    // 3. The parts combined. Very direct light: the pass's and GDPT's, by sample counts.
    Image very_direct = std::move(b.very_direct);
    if (!gdpt_very_direct.empty()) {
        const double pass_spp = std::max(settings.very_direct_samples, 1);
        for (std::size_t i = 0; i < very_direct.pixel_count(); ++i) {
            double n = pass_spp;
            RgbD sum = RgbD::Zero();
            for (int c = 0; c < 3; ++c) sum[c] = pass_spp * very_direct.pixels[3 * i + c];
            for (const auto& [image, counts] : gdpt_very_direct) {
                const double m = counts.pixels[i];
                n += m;
                for (int c = 0; c < 3; ++c) sum[c] += m * image.pixels[3 * i + c];
            }
            for (int c = 0; c < 3; ++c)
                very_direct.pixels[3 * i + c] = static_cast<float>(sum[c] / n);
        }
    }
    // Only parts with variance layers can be weighed: a part stopped (Ctrl-C, the time budget)
    // before it had two samples or batches has none, and is left out when another has them.
    // Left out, a part's estimate is dropped whole, so the combination stays unbiased.
    std::vector<std::size_t> usable;
    for (std::size_t k = 0; k < parts.size(); ++k)
        if (has_variance_layers(parts[k])) usable.push_back(k);
    if (usable.empty()) usable.push_back(parts.size() - 1);  // nothing to weigh: the last part
    if (usable.size() == 1) {
        b = std::move(parts[usable.front()]);
    } else {
        std::vector<const GradientBuffers*> pointers;
        for (std::size_t k : usable) pointers.push_back(&parts[k]);
        CombineSummary summary;
        b = combine_by_inverse_variance(pointers, settings.combine_radius, &summary);
        split.primal_weights = summary.primal_weight;
        split.difference_weights = summary.difference_weight;
    }
    for (std::size_t k : usable) split.parts.push_back(part_names[k]);
    b.very_direct = std::move(very_direct);
    if (chains_ran && settings.bidirectional) {
        // Light tracing is not shifted: it joins the very direct layer, added after the solve.
        for (std::size_t i = 0; i < b.very_direct.pixels.size(); ++i)
            b.very_direct.pixels[i] += chain_part.light.pixels[i];
    }
    out.stats.total_s = seconds_since(start);
    return out;
}

double reconstruct_alpha(const BudgetSplit& split) {
    for (const std::string& part : split.parts)
        if (part == "gdpt") return kCombinedReconstructAlpha;
    return kGdmltReconstructAlpha;
}

BidirectionalChoice choose_bidirectional(const Scene& scene) {
    // 4096 rays with fixed numbers: the choice is a deterministic function of the scene, and
    // the fraction's standard error (under 0.008) is far from mattering at a 0.5 threshold.
    constexpr int kRays = 4096;
    BidirectionalChoice choice;
    int specular = 0;
    IndependentStream stream(derive_stream(0x5CE11E, 0xB1D1));
    for (int i = 0; i < kRays; ++i) {
        const float u_select = stream.next_1d();
        const Vec2f u_position = stream.next_2d();
        const Vec2f u_direction = stream.next_2d();
        const EmittedRay e = scene.sample_emitted_ray(u_select, u_position, u_direction);
        if (!e.valid()) continue;
        ++choice.rays;
        const SurfaceInteraction hit =
            scene.intersect(spawn_ray(e.origin, e.n_geometric, e.direction));
        if (hit.valid() && scene.bsdf_of(hit).roughness_class() == RoughnessClass::Delta)
            ++specular;
    }
    choice.specular_first_hit_fraction =
        choice.rays > 0 ? static_cast<double>(specular) / choice.rays : 0.0;
    choice.bidirectional = choice.specular_first_hit_fraction >= BidirectionalChoice::kThreshold;
    return choice;
}

GdmltSettings gdmlt_settings_from_scene(const IntegratorSettings& integrator) {
    GdmltSettings s;
    if (integrator.desc.type != "gdmlt") {
        read_chain_settings(integrator, nullptr, s);
        return s;
    }
    PropertyReader props(integrator.desc);
    read_chain_settings(integrator, &props, s);
    s.bootstrap_relative_error =
        props.get_float("bootstrap_relative_error", s.bootstrap_relative_error);
    s.primal_weight = props.get_float("primal_weight", s.primal_weight);
    s.gdpt_share = props.get_float("gdpt_share", s.gdpt_share);
    s.pilot_share = props.get_float("pilot_share", s.pilot_share);
    s.combine_radius = props.get_int32("combine_radius", s.combine_radius);
    s.primal_from_offsets = props.get_bool("primal_from_offsets", s.primal_from_offsets);
    s.very_direct_samples = props.get_int32("very_direct_samples", s.very_direct_samples);
    s.bidirectional = props.get_bool("bidirectional", s.bidirectional);
    s.shift_light_tracing = props.get_bool("shift_light_tracing", s.shift_light_tracing);
    s.light_tracing_mis = props.get_float("light_tracing_mis", s.light_tracing_mis);
    s.light_tracing_pass = props.get_bool("light_tracing_pass", s.light_tracing_pass);
    s.light_tracing_share = props.get_float("light_tracing_share", s.light_tracing_share);
    s.light_tracing_spp = props.get_int32("light_tracing_spp", s.light_tracing_spp);
    props.check_all_read();
    validate_gdmlt_settings(s, integrator.desc.loc);
    return s;
}

void validate_gdmlt_settings(const GdmltSettings& s, const FileLoc& loc) {
    validate_chain_settings(s, loc);
    if (!(s.bootstrap_relative_error >= 0.0 && s.bootstrap_relative_error < 1.0))
        throw InputError(loc, "bootstrap_relative_error must lie in [0, 1)");
    if (!(s.primal_weight > 0.0 && std::isfinite(s.primal_weight)))
        throw InputError(loc,
                         "primal_weight must be positive (the chain must reach every pixel "
                         "with light)");
    if (!(s.gdpt_share < 0.0 || s.gdpt_share <= 1.0) || !std::isfinite(s.gdpt_share))
        throw InputError(loc, "gdpt_share must be negative (auto) or lie in [0, 1]");
    if (!(s.pilot_share > 0.0 && s.pilot_share < 0.5))
        throw InputError(loc, "pilot_share must lie in (0, 0.5)");
    if (s.combine_radius < 1 || s.combine_radius > 64)
        throw InputError(loc, "combine_radius must lie in [1, 64]");
    if (s.very_direct_samples < 1) throw InputError(loc, "very_direct_samples must be positive");
    if (s.shift_light_tracing && !s.bidirectional)
        throw InputError(loc, "shift_light_tracing needs bidirectional (no light tracing without)");
    if (!(s.light_tracing_mis > 0.0 && std::isfinite(s.light_tracing_mis)))
        throw InputError(loc, "light_tracing_mis must be positive and finite");
    if (!(s.light_tracing_share > 0.0 && s.light_tracing_share < 1.0))
        throw InputError(loc, "light_tracing_share must lie in (0, 1)");
    if (s.light_tracing_spp < 1) throw InputError(loc, "light_tracing_spp must be positive");
}

}  // namespace gdmlt::mlt
