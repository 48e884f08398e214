// SPDX-License-Identifier: GPL-3.0-or-later
// The gdmlt command line: render, info, reconstruct. The only place that knows argv, output
// paths, signals and terminals.
#include <tbb/global_control.h>
#include <tbb/info.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>

#include "cli/progress.h"
#include "cli/reconstruct_command.h"
#include "cli/validators.h"
#include "core/image/gradient_layers.h"
#include "core/image/image_io.h"
#include "core/math/stopwatch.h"
#include "core/render/adap_selection.h"
#include "core/render/aov_pass.h"
#include "core/render/feature_pass.h"
#include "core/render/film_buffer.h"
#include "core/render/render_bdpt.h"
#include "core/render/render_path.h"
#include "core/render/render_ptracer.h"
#include "core/scene/scene.h"
#include "core/scene/scene_desc.h"
#include "core/scene/spectrum_rgb.h"
#include "mlt/gdmlt.h"
#include "mlt/gdpt.h"
#include "mlt/pssmlt.h"
#include "reconstruct/reconstruct.h"
#include "reconstruct/reconstruct_input.h"

namespace {

using namespace gdmlt;
using json = nlohmann::json;

constexpr const char* kVersion = "0.1.0";

// Set by SIGINT, SIGTERM or SIGHUP; the render polls it, stops within about a second and
// writes what it has. g_stop_signal remembers which, for the exit code (128 + signal).
std::atomic<bool> g_interrupted{false};
std::atomic<int> g_stop_signal{0};

extern "C" void on_stop_signal(int signal) {
    g_stop_signal.store(signal);
    g_interrupted.store(true);
}

constexpr int kStopSignals[] = {SIGINT, SIGTERM, SIGHUP};

struct RenderOptions {
    std::string scene_path;
    std::string output;
    std::vector<std::string> defines;
    std::string integrator;
    int spp = 0;
    double time_s = 0.0;
    int threads = 0;
    std::optional<std::uint64_t> seed;
    std::optional<int> max_depth;
    std::string stats_path;
    bool lenient = false;
    bool quiet = false;
    // PSSMLT knobs (unset: the scene's <integrator> or the defaults).
    std::optional<double> p_large;
    std::vector<double> mutation_size;
    std::optional<double> image_mutation_pixels;
    std::optional<int> chains;
    std::optional<int> bootstrap;
    std::optional<double> mpp;
    std::optional<int> direct_samples;
    std::optional<std::string> bidirectional;  // true | false | auto
    std::optional<bool> shift_light_tracing;
    std::optional<double> light_tracing_mis;
    std::optional<bool> light_tracing_pass;
    std::optional<double> light_tracing_share;
    // Gradient-domain knobs.
    std::string reconstruct_method;
    std::optional<double> alpha;
    std::optional<int> coarse_radius;
    std::optional<double> huber;
    std::string shift;
    // GDMLT knobs.
    std::optional<double> primal_weight;
    std::string gdpt_share;
    std::optional<int> very_direct_samples;
    std::optional<double> bootstrap_error;
    std::optional<bool> primal_from_offsets;
    std::optional<bool> normalise_link_count;
    // Feature pass (ADAP's auxiliary images), with any integrator.
    bool features = false;
    std::optional<int> feature_spp;
    // Neighbours of gdpt and gdmlt: lattice or adap (core/render/adap_selection.h).
    std::string neighbours;
    std::optional<int> adap_k;
    std::optional<int> adap_window;
    std::vector<float> adap_sigma;  // albedo, normal, depth, shape
    bool adap_mutual = false;
};

/// What runs before a gradient-domain integrator: the neighbour graph (null: the lattice) and
/// the seconds the feature pass and selection took, which a time budget includes.
struct NeighbourSetup {
    const NeighbourSet* adap = nullptr;
    double seconds = 0.0;
    json config;  // the neighbour settings, for the EXR header and stats
};

/// What an integrator hands back to the CLI: the image, its statistics, whether it is partial.
struct IntegratorResult {
    Image image;
    std::vector<ExrLayer> extra_layers;  // e.g. primal, dx, dy of gradient-domain renders
    json stats;
    json config;
    bool partial = false;
    std::uint64_t seed = 0;
};

json path_counters_json(const PathCounters& c, double seconds) {
    return {{"camera", c.camera_rays},
            {"bounce", c.bounce_rays},
            {"shadow", c.shadow_rays},
            {"total", c.rays()},
            {"per_s", seconds > 0 ? static_cast<double>(c.rays()) / seconds : 0.0}};
}

std::map<std::string, std::string> parse_defines(const std::vector<std::string>& defines) {
    std::map<std::string, std::string> result;
    for (const std::string& d : defines) {
        const auto eq = d.find('=');
        if (eq == std::string::npos || eq == 0)
            throw InputError("-D expects name=value, got '" + d + "'");
        result[d.substr(0, eq)] = d.substr(eq + 1);
    }
    return result;
}

Scene load_scene(const std::string& path, const std::vector<std::string>& defines, bool lenient) {
    ParseOptions parse_options;
    parse_options.defines = parse_defines(defines);
    const SceneDesc desc = parse_scene_file(path, parse_options);
    BuildOptions build_options;
    build_options.lenient = lenient;
    return build_scene(desc, build_options);
}

json features_json(const SceneFeatures& f) {
    return json{{"diffuse", f.has_diffuse},
                {"glossy", f.has_glossy},
                {"delta_reflection", f.has_delta_reflection},
                {"delta_transmission", f.has_delta_transmission},
                {"transmission", f.has_transmission},
                {"textures", f.has_textures},
                {"area_emitters", f.has_area_emitters},
                {"delta_emitters", f.has_delta_emitters},
                {"infinite_emitters", f.has_infinite_emitters},
                {"specular_chains_possible", f.specular_chains_possible},
                {"bsdf_kinds", f.bsdf_kinds},
                {"emitter_kinds", f.emitter_kinds},
                {"shape_kinds", f.shape_kinds}};
}

/// The files a render writes: the EXR, its PNG preview, and the statistics if asked for.
struct OutputPaths {
    std::string exr, png, stats;
};

/// Where the render's files go, checked before it starts (a long render must not end in an
/// output it cannot or must not write). -o must name an .exr (its PNG goes beside it: "-o
/// x.png" used to write an EXR there and then the PNG over it, and "-o scene.xml" replaced the
/// scene); no two outputs and no output and the scene may be the same file.
OutputPaths output_paths(const RenderOptions& options) {
    namespace fs = std::filesystem;
    OutputPaths paths;
    paths.exr = options.output.empty() ? fs::path(options.scene_path).stem().string() + ".exr"
                                       : options.output;
    std::string extension = fs::path(paths.exr).extension().string();
    for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (extension != ".exr")
        throw InputError("-o must name an .exr file (the PNG preview is written beside it): '" +
                         paths.exr + "'");
    paths.png = fs::path(paths.exr).replace_extension(".png").string();
    paths.stats = options.stats_path;
    const std::vector<std::pair<std::string, std::string>> outputs = {
        {"-o", paths.exr}, {"the PNG preview", paths.png}, {"--stats", paths.stats}};
    for (std::size_t i = 0; i < outputs.size(); ++i) {
        if (outputs[i].second.empty()) continue;
        check_output_path(outputs[i].second, outputs[i].first);
        if (same_file(outputs[i].second, options.scene_path))
            throw InputError(outputs[i].first + " '" + outputs[i].second + "' is the scene file");
        for (std::size_t j = 0; j < i; ++j)
            if (same_file(outputs[i].second, outputs[j].second))
                throw InputError(outputs[i].first + " and " + outputs[j].first +
                                 " name the same file '" + outputs[i].second + "'");
    }
    return paths;
}

/// The settings every per-pixel sampler shares (path tracer, GDPT): spp or time budget, seed,
/// path depth; defaults < scene < command line.
template <typename Settings>
void apply_sample_budget(const Scene& scene, const RenderOptions& options, Settings& settings) {
    settings.spp = options.spp > 0 ? options.spp : scene.sampler().sample_count;
    settings.time_budget_s = options.time_s;
    // --time without --spp: the time alone decides.
    if (options.time_s > 0.0 && options.spp == 0)
        settings.spp = std::numeric_limits<int>::max() / 2;
    settings.seed = options.seed.value_or(scene.sampler().seed);
    settings.path.max_depth = options.max_depth.value_or(scene.integrator().max_depth);
    settings.path.rr_depth = scene.integrator().rr_depth;
    settings.path.hide_emitters = scene.integrator().hide_emitters;
}

manifold::ShiftKind parse_shift(const std::string& shift) {
    if (shift == "auto") return manifold::ShiftKind::Auto;
    if (shift == "reconnect") return manifold::ShiftKind::Reconnect;
    if (shift == "halfvector") return manifold::ShiftKind::HalfVector;
    if (shift == "replay") return manifold::ShiftKind::Replay;
    throw InputError("--shift must be auto, reconnect, halfvector or replay");
}

reconstruct::ReconstructConfig reconstruct_config(const RenderOptions& options) {
    reconstruct::ReconstructConfig rc;
    if (!options.reconstruct_method.empty()) {
        const auto method = reconstruct::parse_method(options.reconstruct_method);
        if (!method) throw InputError("--reconstruct must be l1, l2 or cv");
        rc.method = *method;
    }
    if (options.alpha) rc.alpha = *options.alpha;
    rc.coarse_radius = options.coarse_radius.value_or(reconstruct::kDefaultCoarseRadius);
    rc.huber_k = options.huber.value_or(reconstruct::kDefaultHuber);
    return rc;
}

/// The final image of a gradient-domain render (reconstruction + very direct light) and its
/// raw layers; returns the seconds the solve took.
double solve_gradient_render(const GradientBuffers& buffers,
                             const reconstruct::ReconstructConfig& config, IntegratorResult& r) {
    const Clock::time_point start = Clock::now();
    r.image = reconstruct::reconstruct_buffers(buffers, config).image;
    // Every layer the solve may read (variances, sample counts, graph edges: whichever the
    // integrator filled), so that `gdmlt reconstruct` re-solves the file to this image.
    r.extra_layers = gradient_layers(buffers);
    return seconds_since(start);
}

json shifts_json(const manifold::ShiftCounters& shifts) {
    json by_status = json::object();
    for (int i = 0; i < static_cast<int>(manifold::ShiftStatus::Count); ++i)
        by_status[manifold::to_string(static_cast<manifold::ShiftStatus>(i))] =
            shifts.by_status[static_cast<std::size_t>(i)];
    return {{"total", shifts.shifts},
            {"by_status", by_status},
            {"reconnections", shifts.reconnections},
            {"half_vector_steps", shifts.half_vector_steps},
            {"replay_steps", shifts.replay_steps},
            {"manifold_shifts", shifts.manifold_shifts},
            {"manifold_walks", shifts.manifold_walks},
            {"manifold_newton_iterations", shifts.manifold_iterations}};
}

/// The statistics every chain-runner integrator reports (PSSMLT, GDMLT).
json chain_stats_json(const mlt::ChainStats& s) {
    auto rate = [](std::uint64_t accepted, std::uint64_t proposed) {
        return proposed > 0 ? static_cast<double>(accepted) / static_cast<double>(proposed) : 0.0;
    };
    return {
        {"bootstrap_s", s.bootstrap_s},
        {"chains_s", s.chains_s},
        {"chains", s.chains},
        {"mutations", s.mutations},
        {"mutations_per_s", s.chains_s > 0 ? static_cast<double>(s.mutations) / s.chains_s : 0.0},
        {"acceptance",
         {{"large", rate(s.large_accepted, s.large_proposed)},
          {"small", rate(s.small_accepted, s.small_proposed)},
          {"large_proposed", s.large_proposed},
          {"small_proposed", s.small_proposed}}},
        {"longest_rejection_streak", s.longest_rejection_streak},
        {"median_longest_rejection_streak_per_chain", s.median_longest_rejection_streak},
        {"chain_brightness",
         {{"mean", s.chain_brightness_mean},
          {"relative_spread", s.chain_brightness_relative_spread}}},
        {"normalisation",
         {{"b", s.b},
          {"b_standard_error", s.b_standard_error},
          {"b_samples", s.b_samples},
          {"b_bootstrap", s.b_bootstrap},
          {"b_bootstrap_standard_error", s.b_bootstrap_standard_error},
          {"b_independent", s.b_independent},
          {"b_independent_standard_error", s.b_independent_standard_error},
          {"bootstrap_samples", s.bootstrap_samples},
          {"bootstrap_nonzero", s.bootstrap_nonzero}}},
        {"replay_mismatches", s.replay_mismatches},
        // Stopped before any chain ran: the image is the bootstrap samples' mean.
        {"bootstrap_estimate", s.bootstrap_estimate},
        {"nonfinite_samples_dropped", s.nonfinite_dropped}};
}

/// Mutation knobs shared by the chain integrators; defaults < scene < command line.
void apply_mutation_options(const RenderOptions& options, mlt::MutationSettings& mutation,
                            int& chains, int& bootstrap) {
    if (options.p_large) mutation.p_large = *options.p_large;
    if (!options.mutation_size.empty()) {
        if (options.mutation_size.size() != 2) throw InputError("--mutation-size expects S1,S2");
        mutation.s1 = options.mutation_size[0];
        mutation.s2 = options.mutation_size[1];
    }
    if (options.image_mutation_pixels) mutation.image_s2_pixels = *options.image_mutation_pixels;
    if (options.chains) chains = *options.chains;
    if (options.bootstrap) bootstrap = *options.bootstrap;
}

/// The path tracer, the light tracer (ptracer: light paths per pixel as spp) or BDPT: the same
/// settings and stats.
IntegratorResult run_path(const Scene& scene, const RenderOptions& options, ProgressBar& bar,
                          const std::string& integrator) {
    RenderSettings settings;
    apply_sample_budget(scene, options, settings);
    // Mitsuba 3's `moment`: the path tracer's samples' first and second moments in XYZ.
    const std::string& moment = scene.integrator().moment;
    settings.second_moment = !moment.empty() && integrator == "path";

    IntegratorResult r;
    r.seed = settings.seed;
    r.config = {
        {"integrator", integrator},
        {"spp", options.time_s > 0.0 && options.spp == 0 ? json(nullptr) : json(settings.spp)},
        {"time_budget_s", settings.time_budget_s},
        {"seed", settings.seed},
        {"max_depth", settings.path.max_depth},
        {"rr_depth", settings.path.rr_depth},
        {"hide_emitters", settings.path.hide_emitters}};
    const auto on_progress = [&](const RenderProgress& p) {
        bar.update(p.fraction, p.samples, p.elapsed_s);
    };
    BdptRenderSettings bdpt;
    bdpt.spp = settings.spp;
    bdpt.time_budget_s = settings.time_budget_s;
    bdpt.seed = settings.seed;
    bdpt.bdpt.max_depth = settings.path.max_depth;
    bdpt.bdpt.rr_depth = settings.path.rr_depth;
    bdpt.bdpt.hide_emitters = settings.path.hide_emitters;
    const RenderOutput out =
        integrator == "ptracer" ? render_ptracer(scene, settings, &g_interrupted, on_progress)
        : integrator == "bdpt"  ? render_bdpt(scene, bdpt, &g_interrupted, on_progress)
                                : render_path(scene, settings, &g_interrupted, on_progress);
    const RenderStats& s = out.stats;
    r.image = out.image;
    r.partial = s.interrupted;
    if (!out.second_moment.pixels.empty()) {
        // Layers `<name>.X/Y/Z` (the mean) and `m2_<name>.X/Y/Z`, Mitsuba 3's channel names.
        Image first(out.image.width, out.image.height, 3);
        for (std::size_t i = 0; i < out.image.pixel_count(); ++i) {
            const Vec3f xyz = linear_srgb_to_xyz(Rgb(
                out.image.pixels[3 * i], out.image.pixels[3 * i + 1], out.image.pixels[3 * i + 2]));
            for (int c = 0; c < 3; ++c) first.pixels[3 * i + static_cast<std::size_t>(c)] = xyz[c];
        }
        r.extra_layers.push_back(ExrLayer{moment, {"X", "Y", "Z"}, std::move(first)});
        r.extra_layers.push_back(ExrLayer{"m2_" + moment, {"X", "Y", "Z"}, out.second_moment});
    }
    r.stats = {
        {"render_s", s.render_s},
        {"samples", s.samples},
        {"spp_completed", s.spp_completed},
        {"passes", s.passes},
        {"samples_per_s", s.render_s > 0 ? static_cast<double>(s.samples) / s.render_s : 0.0},
        {"rays", path_counters_json(s.counters, s.render_s)},
        {"nonfinite_samples_dropped", s.nonfinite_samples_dropped}};
    return r;
}

/// --bidirectional true|false|auto into `bidirectional`. Auto (asked for, or for GDMLT
/// whenever neither the flag nor the scene's integrator says) lets the scene decide
/// (mlt::choose_bidirectional); the choice is returned for the stats.
std::optional<mlt::BidirectionalChoice> resolve_bidirectional(const Scene& scene,
                                                              const RenderOptions& options,
                                                              bool auto_by_default,
                                                              bool& bidirectional) {
    const bool scene_says = scene.integrator().desc.find("bidirectional") != nullptr;
    const bool automatic =
        options.bidirectional ? *options.bidirectional == "auto" : auto_by_default && !scene_says;
    if (!automatic) {
        if (options.bidirectional) bidirectional = *options.bidirectional == "true";
        return std::nullopt;
    }
    const mlt::BidirectionalChoice choice = mlt::choose_bidirectional(scene);
    bidirectional = choice.bidirectional;
    return choice;
}

json bidirectional_choice_json(const std::optional<mlt::BidirectionalChoice>& choice) {
    if (!choice) return nullptr;
    return {{"bidirectional", choice->bidirectional},
            {"specular_first_hit_fraction", choice->specular_first_hit_fraction},
            {"rays", choice->rays},
            {"threshold", mlt::BidirectionalChoice::kThreshold}};
}

/// PSSMLT, unidirectional or bidirectional, or (`integrator` "mmlt") multiplexed MLT.
IntegratorResult run_pssmlt(const Scene& scene, const RenderOptions& options, ProgressBar& bar,
                            const std::string& integrator) {
    mlt::PssmltSettings settings = mlt::pssmlt_settings_from_scene(scene.integrator());
    settings.multiplexed = integrator == "mmlt";
    apply_mutation_options(options, settings.mutation, settings.chains, settings.bootstrap_samples);
    if (options.mpp) settings.mutations_per_pixel = *options.mpp;
    if (options.direct_samples) settings.direct_samples = *options.direct_samples;
    const std::optional<mlt::BidirectionalChoice> choice =
        resolve_bidirectional(scene, options, false, settings.bidirectional);
    // --spp gives a PSSMLT budget of as many mutations per pixel.
    if (!options.mpp && options.spp > 0) settings.mutations_per_pixel = options.spp;
    settings.time_budget_s = options.time_s;
    settings.seed = options.seed.value_or(scene.sampler().seed);
    if (options.max_depth) settings.path.max_depth = *options.max_depth;
    mlt::validate_pssmlt_settings(settings, FileLoc{"command line", 0, 0});

    IntegratorResult r;
    r.seed = settings.seed;
    r.config = {
        {"integrator", integrator},
        {"mutations_per_pixel",
         options.time_s > 0.0 && !options.mpp ? json(nullptr) : json(settings.mutations_per_pixel)},
        {"time_budget_s", settings.time_budget_s},
        {"seed", settings.seed},
        {"p_large", settings.mutation.p_large},
        {"mutation_size", {settings.mutation.s1, settings.mutation.s2}},
        {"image_mutation_size_pixels", settings.mutation.image_s2_pixels},
        {"chains", settings.chains},
        {"bootstrap_samples", settings.bootstrap_samples},
        {"kelemen_style_weights", settings.kelemen_weights},
        {"direct_samples", settings.direct_samples},
        {"bidirectional", settings.bidirectional},
        {"bidirectional_auto", bidirectional_choice_json(choice)},
        {"max_depth", settings.path.max_depth},
        {"rr_depth", settings.path.rr_depth},
        {"hide_emitters", settings.path.hide_emitters}};
    const mlt::PssmltOutput out = mlt::render_pssmlt(
        scene, settings, &g_interrupted,
        [&](double fraction, double elapsed) { bar.update(fraction, 0, elapsed); });
    const mlt::PssmltStats& s = out.stats;
    r.image = out.image;
    r.partial = s.interrupted;
    r.stats = chain_stats_json(s);
    r.stats["render_s"] = s.total_s;
    r.stats["direct_s"] = s.direct_s;
    r.stats["rays"] = path_counters_json(s.counters, s.total_s);
    return r;
}

/// The time left for sampling once the neighbour setup has run (a budget covers the whole
/// render, so that lattice and adap compare at equal time).
double remaining_budget(double time_s, const NeighbourSetup& setup) {
    return time_s > 0.0 ? std::max(time_s - setup.seconds, 1e-3) : 0.0;
}

IntegratorResult run_gdpt(const Scene& scene, const RenderOptions& options,
                          const NeighbourSetup& setup, ProgressBar& bar) {
    mlt::GdptSettings settings;
    apply_sample_budget(scene, options, settings);
    settings.time_budget_s = remaining_budget(settings.time_budget_s, setup);
    const std::string shift = options.shift.empty() ? "auto" : options.shift;
    settings.shift = parse_shift(shift);
    const reconstruct::ReconstructConfig rc = reconstruct_config(options);

    IntegratorResult r;
    r.seed = settings.seed;
    r.config = {
        {"integrator", "gdpt"},
        {"spp", options.time_s > 0.0 && options.spp == 0 ? json(nullptr) : json(settings.spp)},
        {"time_budget_s", settings.time_budget_s},
        {"seed", settings.seed},
        {"shift", shift},
        {"neighbours", setup.config},
        {"reconstruct", reconstruct::to_string(rc.method)},
        {"alpha", rc.alpha},
        {"coarse_radius", rc.coarse_radius},
        {"huber", rc.huber_k},
        {"max_depth", settings.path.max_depth},
        {"hide_emitters", settings.path.hide_emitters}};
    const Film& film = scene.camera().film();
    const mlt::GdptOutput out = mlt::render_gdpt(
        scene, settings,
        setup.adap ? *setup.adap : NeighbourSet::lattice(film.crop_width, film.crop_height),
        &g_interrupted, [&](double fraction, double elapsed) { bar.update(fraction, 0, elapsed); });
    const double solve_s = solve_gradient_render(out.buffers, rc, r);
    const mlt::GdptStats& s = out.stats;
    r.partial = s.interrupted;
    r.stats = {
        {"render_s", setup.seconds + s.render_s + solve_s},
        {"sampling_s", s.render_s},
        {"reconstruct_s", solve_s},
        {"samples", s.samples},
        {"spp_completed", s.spp_completed},
        {"samples_per_s", s.render_s > 0 ? static_cast<double>(s.samples) / s.render_s : 0.0},
        {"rays", path_counters_json(s.counters, s.render_s)},
        {"shifts", shifts_json(s.shifts)},
        {"nonfinite_samples_dropped", s.nonfinite_dropped}};
    return r;
}

IntegratorResult run_gdmlt(const Scene& scene, const RenderOptions& options,
                           const NeighbourSetup& setup, ProgressBar& bar) {
    mlt::GdmltSettings settings = mlt::gdmlt_settings_from_scene(scene.integrator());
    apply_mutation_options(options, settings.mutation, settings.chains, settings.bootstrap_samples);
    if (options.mpp) settings.mutations_per_pixel = *options.mpp;
    // --spp gives a budget of as many proposals per pixel.
    if (!options.mpp && options.spp > 0) settings.mutations_per_pixel = options.spp;
    if (options.primal_weight) settings.primal_weight = *options.primal_weight;
    if (!options.gdpt_share.empty())
        settings.gdpt_share = options.gdpt_share == "auto" ? -1.0 : std::stod(options.gdpt_share);
    if (options.very_direct_samples) settings.very_direct_samples = *options.very_direct_samples;
    if (options.bootstrap_error) settings.bootstrap_relative_error = *options.bootstrap_error;
    if (options.primal_from_offsets) settings.primal_from_offsets = *options.primal_from_offsets;
    if (options.normalise_link_count) settings.normalise_link_count = *options.normalise_link_count;
    const std::optional<mlt::BidirectionalChoice> choice =
        resolve_bidirectional(scene, options, true, settings.bidirectional);
    if (options.shift_light_tracing) settings.shift_light_tracing = *options.shift_light_tracing;
    if (options.light_tracing_mis) settings.light_tracing_mis = *options.light_tracing_mis;
    if (options.light_tracing_pass) settings.light_tracing_pass = *options.light_tracing_pass;
    if (options.light_tracing_share) settings.light_tracing_share = *options.light_tracing_share;
    settings.time_budget_s = remaining_budget(options.time_s, setup);
    settings.seed = options.seed.value_or(scene.sampler().seed);
    if (options.max_depth) settings.path.max_depth = *options.max_depth;
    const std::string shift = options.shift.empty() ? "auto" : options.shift;
    settings.shift = parse_shift(shift);
    mlt::validate_gdmlt_settings(settings, FileLoc{"command line", 0, 0});
    reconstruct::ReconstructConfig rc = reconstruct_config(options);

    const json gdpt_share_json =
        settings.gdpt_share < 0.0 ? json("auto") : json(settings.gdpt_share);
    IntegratorResult r;
    r.seed = settings.seed;
    r.config = {{"integrator", "gdmlt"},
                {"mutations_per_pixel", options.time_s > 0.0 && !options.mpp && options.spp == 0
                                            ? json(nullptr)
                                            : json(settings.mutations_per_pixel)},
                {"time_budget_s", settings.time_budget_s},
                {"seed", settings.seed},
                {"shift", shift},
                {"neighbours", setup.config},
                {"primal_weight", settings.primal_weight},
                {"gdpt_share", gdpt_share_json},
                {"pilot_share", settings.pilot_share},
                {"combine_radius", settings.combine_radius},
                {"primal_from_offsets", settings.primal_from_offsets},
                {"normalise_link_count", settings.normalise_link_count},
                {"bidirectional", settings.bidirectional},
                {"bidirectional_auto", bidirectional_choice_json(choice)},
                {"shift_light_tracing", settings.shift_light_tracing},
                {"light_tracing_mis", settings.light_tracing_mis},
                {"light_tracing_pass", settings.light_tracing_pass},
                {"light_tracing_share", settings.light_tracing_share},
                {"reconstruct", reconstruct::to_string(rc.method)},
                {"alpha", rc.alpha},
                {"coarse_radius", rc.coarse_radius},
                {"huber", rc.huber_k},
                {"p_large", settings.mutation.p_large},
                {"mutation_size", {settings.mutation.s1, settings.mutation.s2}},
                {"image_mutation_size_pixels", settings.mutation.image_s2_pixels},
                {"chains", settings.chains},
                {"bootstrap_samples", settings.bootstrap_samples},
                {"bootstrap_relative_error", settings.bootstrap_relative_error},
                {"very_direct_samples", settings.very_direct_samples},
                {"kelemen_style_weights", settings.kelemen_weights},
                {"max_depth", settings.path.max_depth},
                {"hide_emitters", settings.path.hide_emitters}};
    const Film& film = scene.camera().film();
    const mlt::GdmltOutput out = mlt::render_gdmlt(
        scene, settings,
        setup.adap ? *setup.adap : NeighbourSet::lattice(film.crop_width, film.crop_height),
        &g_interrupted, [&](double fraction, double elapsed) { bar.update(fraction, 0, elapsed); });
    // alpha follows what the layers hold (chains alone, or GDPT passes among them).
    if (!options.alpha) {
        rc.alpha = mlt::reconstruct_alpha(out.stats.split);
        r.config["alpha"] = rc.alpha;
    }
    const double solve_s = solve_gradient_render(out.buffers, rc, r);
    r.extra_layers.push_back(ExrLayer{"sample_density", {"Y"}, out.sample_density});
    const mlt::GdmltStats& s = out.stats;
    r.partial = s.interrupted;
    r.stats = chain_stats_json(s);
    r.stats["render_s"] = setup.seconds + s.total_s + solve_s;
    r.stats["sampling_s"] = s.total_s;
    r.stats["very_direct_s"] = s.very_direct_s;
    r.stats["light_tracing_s"] = s.light_tracing_s;  // the light tracing pass (bidirectional)
    r.stats["light_paths"] = s.light_paths;
    r.stats["budget_split"] = {{"mode", s.split.mode},
                               {"decision", s.split.decision},
                               {"reason", s.split.reason},
                               {"gdpt_noise", s.split.gdpt_noise},
                               {"chain_noise", s.split.chain_noise},
                               {"gdpt_efficiency", s.split.gdpt_efficiency},
                               {"chain_efficiency", s.split.chain_efficiency},
                               {"slots_compared", s.split.slots_compared},
                               {"cost_unit", s.split.cost_unit},
                               {"gdpt_s", s.split.gdpt_s},
                               {"gdpt_samples", s.split.gdpt_samples},
                               {"parts", s.split.parts},
                               {"primal_weights", s.split.primal_weights},
                               {"difference_weights", s.split.difference_weights}};
    r.stats["reconstruct_s"] = solve_s;
    r.stats["proposals_per_s"] =
        s.chains_s > 0 ? static_cast<double>(s.mutations) / s.chains_s : 0.0;
    r.stats["rays"] = path_counters_json(s.counters, s.total_s);
    r.stats["shifts"] = shifts_json(s.shifts);
    return r;
}

/// Bytes per crop-window pixel a render holds at its peak, measured on cbox at 1 spp as
/// (maximum resident set size at 1024^2 - at 256^2) / (1024^2 - 256^2) with /usr/bin/time -v:
/// path 36, pssmlt 42, gdpt 394, gdmlt 316; the feature pass adds 50 and ADAP's graph up to
/// 282 (gdmlt; 202 with gdpt). Rounded up here by a quarter. PSSMLT's peak grew to 62 (128^2 to
/// 1024^2) when the bootstrap's splats got their own sums (24 bytes per slot; GDMLT's peak is in
/// its reconstruction, after they are freed): 78. Cli.TheMemoryEstimateIsAtLeastWhatEach...
/// checks every estimate against a measured slope. GDMLT's peak rose to 517 (128^2 to 384^2)
/// with its variance layers (batch sums, 36 bytes per slot) and the GDPT passes of its budget
/// split, whose buffers wait for the combination while the chains run: 650.
double peak_bytes_per_pixel(const std::string& integrator, bool features, bool adap,
                            bool splat_film) {
    // The path tracer with a filter wider than a pixel also keeps its splatting film
    // (core/render/splat_film.h): a pass's records (4 spp x 24 bytes) and the weighted sums
    // (32 bytes) beside the box film: measured 168 (128^2 to 1024^2, 8 spp), rounded up by
    // about a quarter.
    if (integrator == "path" && splat_film) return 216.0 + (features ? 63.0 : 0.0);
    double bytes = integrator == "gdpt"                             ? 493.0
                   : integrator == "gdmlt"                          ? 650.0
                   : integrator == "pssmlt" || integrator == "mmlt" ? 78.0
                   // The light tracer: measured 36 without an environment, which adds one
                   // more double RGB sum (24) for the camera rays that see it.
                   : integrator == "ptracer" ? 75.0
                   // BDPT: measured 70 (the film, a double RGB light image and a pass's
                   // splats).
                   : integrator == "bdpt" ? 90.0
                                          : 45.0;
    if (features) bytes += 63.0;
    if (adap) bytes += 353.0;
    return bytes;
}

/// Refuses a render whose buffers alone would not fit into the machine's memory, before
/// allocating them: `-D res=60000` used to allocate until std::bad_alloc ("internal error").
void check_memory(const Film& film, const std::string& integrator, bool features, bool adap) {
    const double pixels = static_cast<double>(film.crop_width) * film.crop_height;
    const double need =
        pixels * peak_bytes_per_pixel(integrator, features, adap, !film.filter.is_box());
    const long pages = ::sysconf(_SC_PHYS_PAGES), page_size = ::sysconf(_SC_PAGE_SIZE);
    if (pages <= 0 || page_size <= 0) return;  // unknown: let the allocation decide
    const double have = static_cast<double>(pages) * static_cast<double>(page_size);
    if (need > have) {
        char text[256];
        std::snprintf(text, sizeof(text),
                      "a %dx%d %s render needs about %.1f GiB of memory, more than this "
                      "machine's %.1f GiB",
                      film.crop_width, film.crop_height, integrator.c_str(), need / (1 << 30),
                      have / (1 << 30));
        throw InputError(text);
    }
}

int run_render(const RenderOptions& options) {
    // The stop signals are caught from before the scene loads until the outputs are written: a
    // render stops within about a second and writes what it has, and a second Ctrl-C while
    // writing is ignored instead of killing the process half-way through a file.
    g_interrupted.store(false);
    g_stop_signal.store(0);
    for (const int signal : kStopSignals) std::signal(signal, on_stop_signal);
    Scene scene = load_scene(options.scene_path, options.defines, options.lenient);

    // Effective configuration: defaults < scene file < command line.
    const std::string integrator =
        options.integrator.empty() ? scene.integrator().type : options.integrator;
    if (integrator != "path" && integrator != "ptracer" && integrator != "bdpt" &&
        integrator != "pssmlt" && integrator != "mmlt" && integrator != "gdpt" &&
        integrator != "gdmlt")
        throw InputError(
            "integrator '" + integrator +
            "' is not available (available: path, ptracer, bdpt, pssmlt, mmlt, gdpt, gdmlt)");
    if (options.max_depth && (*options.max_depth == 0 || *options.max_depth < -1))
        throw InputError("--max-depth must be -1 or at least 1");
    const bool gradient_domain = integrator == "gdpt" || integrator == "gdmlt";
    // The film's filter: the path tracer splats as Mitsuba 3's film (core/render/splat_film.h);
    // the other pixel passes draw positions from it and light paths splat through it
    // (core/camera/pixel_filter.h); the gradient-domain integrators apply it to the
    // reconstructed image.
    const PixelFilter film_filter = scene.camera().film().filter;
    if (gradient_domain) scene.set_film_filter(PixelFilter());
    const std::string neighbours = options.neighbours.empty() ? "lattice" : options.neighbours;
    if (neighbours != "lattice" && neighbours != "adap")
        throw InputError("--neighbours must be lattice or adap");
    const bool adap = neighbours == "adap";
    if (adap && !gradient_domain)
        throw InputError("--neighbours adap needs a gradient-domain integrator (gdpt, gdmlt)");
    const bool adap_knobs =
        options.adap_k || options.adap_window || !options.adap_sigma.empty() || options.adap_mutual;
    if (adap_knobs && !adap) throw InputError("--adap-* options need --neighbours adap");
    if (options.feature_spp && !options.features && !adap)
        throw InputError("--feature-spp needs --features or --neighbours adap");
    AdapSettings adap_settings;
    if (options.adap_k) adap_settings.neighbours = *options.adap_k;
    if (options.adap_window) adap_settings.window_radius = *options.adap_window;
    if (!options.adap_sigma.empty()) {
        if (options.adap_sigma.size() != 4)
            throw InputError("--adap-sigma expects 4 bandwidths: albedo,normal,depth,shape");
        adap_settings.sigma_albedo = options.adap_sigma[0];
        adap_settings.sigma_normal = options.adap_sigma[1];
        adap_settings.sigma_depth = options.adap_sigma[2];
        adap_settings.sigma_shape = options.adap_sigma[3];
    }
    adap_settings.mutual = options.adap_mutual;
    if (adap_settings.neighbours < 1 || adap_settings.window_radius < 1 ||
        adap_settings.window_radius > 8)
        throw InputError("--adap-k must be at least 1 and --adap-window lie in [1, 8]");
    for (const float sigma : options.adap_sigma)
        if (!std::isfinite(sigma) || sigma < 0.f)
            throw InputError("--adap-sigma: bandwidths must be finite and >= 0 (0 = off)");

    const int threads = options.threads > 0 ? options.threads : tbb::info::default_concurrency();
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                              static_cast<std::size_t>(threads));

    const Film& film = scene.camera().film();
    check_memory(film, integrator, options.features || adap, adap);
    const OutputPaths paths = output_paths(options);
    if (!options.quiet)
        std::cerr << "gdmlt: rendering " << options.scene_path << " (" << film.crop_width << "x"
                  << film.crop_height << ", " << integrator << ", " << threads << " threads)\n";

    if (g_interrupted.load()) {
        // Stopped while the scene loaded: there is nothing to write yet.
        std::cerr << "gdmlt: interrupted before rendering; nothing written\n";
        return 128 + g_stop_signal.load();
    }
    // The feature pass runs first, so that ADAP can choose neighbours from its images; it
    // derives its own streams from the render's seed (feature_pass.h).
    std::optional<FeatureImages> features;
    double feature_pass_s = 0.0;
    const int feature_spp = options.feature_spp.value_or(4);
    if (options.features || adap) {
        FeatureSettings fs;
        fs.spp = feature_spp;
        fs.seed = options.seed.value_or(scene.sampler().seed);
        const Clock::time_point start = Clock::now();
        features = render_features(scene, fs, &g_interrupted);
        feature_pass_s = seconds_since(start);
        if (!options.quiet)
            std::cerr << "gdmlt: feature pass: " << features->spp << " spp in " << feature_pass_s
                      << " s\n";
    }
    // ADAP's graph, frozen before sampling starts.
    NeighbourSetup setup;
    std::optional<NeighbourSet> adap_set;
    json selection_stats;
    setup.config = {{"kind", neighbours}};
    if (adap) {
        const Clock::time_point start = Clock::now();
        adap_set = select_adap_neighbours(*features, adap_settings);
        const double selection_s = seconds_since(start);
        setup.adap = &*adap_set;
        setup.seconds = feature_pass_s + selection_s;
        setup.config.update({{"k", adap_settings.neighbours},
                             {"window_radius", adap_settings.window_radius},
                             {"sigma",
                              {{"albedo", adap_settings.sigma_albedo},
                               {"normal", adap_settings.sigma_normal},
                               {"depth", adap_settings.sigma_depth},
                               {"shape", adap_settings.sigma_shape}}},
                             {"mutual", adap_settings.mutual},
                             {"feature_spp", feature_spp}});
        selection_stats = {
            {"selection_s", selection_s},
            {"edges", adap_set->edges().size()},
            {"lattice_edges",
             static_cast<std::size_t>(film.crop_width - 1) * film.crop_height +
                 static_cast<std::size_t>(film.crop_width) * (film.crop_height - 1)},
            {"mean_links_per_pixel", static_cast<double>(adap_set->link_count()) /
                                         static_cast<double>(adap_set->pixel_count())},
            {"max_links_per_pixel", adap_set->max_links()}};
    }
    ProgressBar bar(isatty(STDERR_FILENO) != 0, options.quiet);
    IntegratorResult result = integrator == "pssmlt" || integrator == "mmlt"
                                  ? run_pssmlt(scene, options, bar, integrator)
                              : integrator == "gdpt"  ? run_gdpt(scene, options, setup, bar)
                              : integrator == "gdmlt" ? run_gdmlt(scene, options, setup, bar)
                                                      : run_path(scene, options, bar, integrator);
    if (features) {
        // Interrupted during the feature pass: the render stopped at once too, and both are
        // partial.
        result.partial = result.partial || features->interrupted;
        result.extra_layers.push_back(ExrLayer{"albedo", {"R", "G", "B"}, features->albedo});
        result.extra_layers.push_back(ExrLayer{"normal", {"X", "Y", "Z"}, features->normal});
        result.extra_layers.push_back(ExrLayer{"depth", {"Z"}, features->depth});
        result.extra_layers.push_back(ExrLayer{"shape_id", {"Y"}, features->shape_id});
        result.extra_layers.push_back(
            ExrLayer{"albedo_variance", {"Y"}, features->albedo_variance});
        result.extra_layers.push_back(
            ExrLayer{"normal_variance", {"Y"}, features->normal_variance});
        result.extra_layers.push_back(ExrLayer{"depth_variance", {"Y"}, features->depth_variance});
    }
    if (!scene.integrator().aovs.empty()) {
        // Mitsuba 3's `aov` integrator: the first hit's variables, averaged over the camera
        // rays of (at most 64 of) the render's samples per pixel.
        const int aov_spp =
            std::clamp(options.spp > 0 ? options.spp : scene.sampler().sample_count, 1, 64);
        for (ExrLayer& layer :
             render_aovs(scene, scene.integrator().aovs, aov_spp,
                         options.seed.value_or(scene.sampler().seed), &g_interrupted))
            result.extra_layers.push_back(std::move(layer));
    }
    if (gradient_domain) result.image = filter_image(result.image, film_filter);
    bar.finish(result.partial);

    json config = result.config;
    config["film_filter"] = {
        {"name", film_filter.name()},
        {"radius", film_filter.radius()},
        {"applied", film_filter.is_box() ? "pixel"
                    : gradient_domain    ? "image convolution after the reconstruction"
                    : integrator == "path"
                        ? "splatted: weighted mean of the samples within the radius (Mitsuba 3's "
                          "film)"
                        : "positions drawn from the filter; light paths splatted"}};
    // Which camera ran (and, for the thin lens, that its rays draw two more numbers).
    config["camera"] = projection_name(scene.camera().projection());
    // Mitsuba 3's `moment` layers: written by the path tracer, whose pixels are means of
    // independent samples; light tracing splats and the chains' and gradient renders' pixels
    // are not, so they render the image alone (and say so).
    if (!scene.integrator().moment.empty()) {
        const bool written = integrator == "path";
        config["moment_layers"] = written;
        if (!written && !options.quiet)
            std::cerr << "warning: moment: the first and second moment layers are written for "
                         "the path tracer only; "
                      << integrator << " renders the image alone\n";
    }
    config["scene"] = options.scene_path;
    config["threads"] = threads;
    config["defines"] = options.defines;
    config["version"] = kVersion;
    config["features"] = options.features;
    config["feature_spp"] = features ? json(feature_spp) : json(nullptr);
    json stats = result.stats;
    if (adap) stats["neighbour_selection"] = selection_stats;
    if (features) {
        stats["feature_pass_s"] = feature_pass_s;
        stats["feature_spp_completed"] = features->spp;
        stats["feature_rays"] = path_counters_json(features->counters, feature_pass_s);
    }
    stats["config"] = config;
    stats["partial"] = result.partial;
    stats["scene"] = {{"features", features_json(scene.features())}, {"counts", scene.counts()}};
    stats["machinery"] = {
        {"next_event_estimation", integrator != "ptracer"},
        {"light_tracing", integrator == "ptracer" || integrator == "bdpt" || integrator == "mmlt" ||
                              config.value("bidirectional", false)},
        {"shift_mappings", gradient_domain},
        {"half_vector_or_replay_through_specular",
         gradient_domain && scene.features().specular_chains_possible},
        {"manifold_solver", gradient_domain && scene.features().specular_chains_possible},
        {"markov_chains", integrator == "pssmlt" || integrator == "mmlt" || integrator == "gdmlt"},
        {"why",
         scene.features().specular_chains_possible
             ? "specular chains are possible: the gdpt and gdmlt auto shift walks them (path "
               "and pssmlt never need it)"
             : "no delta or glossy surface: no specular chain can occur, no half-vector or "
               "manifold code runs"}};

    ExrAttributes attributes;
    attributes["gdmlt/config"] = config.dump();
    attributes["gdmlt/seed"] = std::to_string(result.seed);
    attributes["gdmlt/version"] = kVersion;
    attributes["gdmlt/partial"] = result.partial ? "true" : "false";

    const std::string& output = paths.exr;
    std::vector<ExrLayer> layers = {ExrLayer{"", {"R", "G", "B"}, result.image}};
    layers.insert(layers.end(), result.extra_layers.begin(), result.extra_layers.end());
    const std::string& png = paths.png;
    // All or nothing: a failed write (a full disk) replaces none of the files. Written in the
    // order of their usual sizes, which lets the CLI test fail each one alone under a file-size
    // limit.
    OutputFiles files;
    files.add_png_srgb(png, result.image);
    files.add_exr(output, layers, attributes);
    if (!options.stats_path.empty()) files.add_text(options.stats_path, stats.dump(2) + "\n");
    files.commit();

    for (const int signal : kStopSignals) std::signal(signal, SIG_DFL);

    if (!options.quiet)
        std::cerr << "gdmlt: wrote " << output << " and " << png
                  << (result.partial ? " (partial: interrupted)" : "") << " in "
                  << stats.value("render_s", 0.0) << " s\n";
    // A partial render exits as the signal that stopped it would have (130 for Ctrl-C).
    const int signal = g_stop_signal.load();
    return result.partial ? 128 + (signal > 0 ? signal : SIGINT) : 0;
}

int run_info(const std::string& scene_path, const std::vector<std::string>& defines, bool lenient) {
    const Scene scene = load_scene(scene_path, defines, lenient);
    const auto bounds = scene.bounds();
    const Film& film = scene.camera().film();
    json info = {
        {"scene", scene_path},
        {"counts", scene.counts()},
        {"bounds",
         {{"min", {bounds.min().x(), bounds.min().y(), bounds.min().z()}},
          {"max", {bounds.max().x(), bounds.max().y(), bounds.max().z()}}}},
        {"film",
         {{"width", film.width},
          {"height", film.height},
          {"crop", {film.crop_offset_x, film.crop_offset_y, film.crop_width, film.crop_height}}}},
        {"integrator",
         {{"type", scene.integrator().type},
          {"max_depth", scene.integrator().max_depth},
          {"rr_depth", scene.integrator().rr_depth},
          {"hide_emitters", scene.integrator().hide_emitters}}},
        {"sampler",
         {{"sample_count", scene.sampler().sample_count}, {"seed", scene.sampler().seed}}},
        {"features", features_json(scene.features())}};
    std::cout << info.dump(2) << "\n";
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    CLI::App app{"gdmlt: gradient-domain Metropolis light transport with manifold exploration"};
    app.set_version_flag("--version", kVersion);
    app.require_subcommand(1);
    int exit_code = 0;

    RenderOptions render;
    CLI::App* render_cmd = app.add_subcommand("render", "Render a Mitsuba XML scene to EXR + PNG");
    render_cmd->add_option("scene", render.scene_path, "Scene file (Mitsuba XML, version 0.6 or 3)")
        ->required();
    render_cmd->add_option("-o,--output", render.output,
                           "Output EXR (a PNG preview is written beside it)");
    render_cmd->add_option("-D,--define", render.defines,
                           "Scene parameter name=value (overrides <default>)");
    render_cmd->add_option(
        "--integrator", render.integrator,
        "path | ptracer | bdpt | pssmlt | mmlt | gdpt | gdmlt (default: the scene's)");
    auto* spp_opt =
        render_cmd->add_option("--spp", render.spp, "Samples per pixel (default: the scene's)")
            ->check(CLI::PositiveNumber);
    render_cmd
        ->add_option("--time", render.time_s,
                     "Time budget in seconds (with --spp: whichever ends first)")
        ->check(CLI::PositiveNumber)
        ->check(finite_number());
    (void)spp_opt;
    render_cmd->add_option("-t,--threads", render.threads, "Threads (default: all cores)")
        ->check(CLI::NonNegativeNumber);
    render_cmd->add_option("--seed", render.seed,
                           "Random seed (default: the scene's sampler seed)");
    render_cmd->add_option("--max-depth", render.max_depth,
                           "Longest path in segments, -1 = unbounded");
    render_cmd->add_option("--stats", render.stats_path, "Write statistics JSON here");
    render_cmd->add_flag("--lenient", render.lenient,
                         "Unknown plugins/properties are warnings, not errors");
    render_cmd->add_flag("-q,--quiet", render.quiet, "No progress output");
    render_cmd
        ->add_option("--p-large", render.p_large,
                     "PSSMLT/GDMLT: large-step probability (0.3 / 0.7)")
        ->check(CLI::Range(0.0, 1.0))
        ->check(finite_number());
    render_cmd
        ->add_option("--mutation-size", render.mutation_size,
                     "PSSMLT: small-step sizes S1,S2 (1/1024,1/64)")
        ->delimiter(',')
        ->expected(2)
        ->check(finite_number());
    render_cmd
        ->add_option("--image-mutation-size", render.image_mutation_pixels,
                     "PSSMLT: small-step size S2 of the image coordinates, in pixels")
        ->check(finite_number());
    render_cmd->add_option("--chains", render.chains,
                           "PSSMLT/GDMLT: number of Markov chains (0: automatic)");
    render_cmd->add_option("--bootstrap", render.bootstrap,
                           "PSSMLT/GDMLT: bootstrap samples estimating b (100000)");
    render_cmd
        ->add_option("--mpp", render.mpp, "PSSMLT/GDMLT: mutations per pixel (64 / 16, or --spp)")
        ->check(finite_number());
    render_cmd->add_option("--direct-samples", render.direct_samples,
                           "PSSMLT: render direct illumination separately with N path-traced spp");
    render_cmd->add_option("--shift-light-tracing", render.shift_light_tracing,
                           "GDMLT with --bidirectional: shift light tracing too (false)");
    render_cmd
        ->add_option("--light-tracing-mis", render.light_tracing_mis,
                     "GDMLT with --bidirectional: factor of light tracing's density in the MIS "
                     "weights (1)")
        ->check(CLI::PositiveNumber & finite_number());
    render_cmd->add_option("--light-tracing-pass", render.light_tracing_pass,
                           "GDMLT with --bidirectional: light tracing from a pass of its own, not "
                           "from the chains (true)");
    render_cmd
        ->add_option("--light-tracing-share", render.light_tracing_share,
                     "GDMLT, light tracing pass: its fraction of the time budget (0.3)")
        ->check(CLI::Range(0.0, 1.0) & finite_number());
    render_cmd
        ->add_option("--bidirectional", render.bidirectional,
                     "PSSMLT, GDMLT: true = bidirectional (BDPT) samples, auto = when the light "
                     "leaves its emitters through smooth surfaces (PSSMLT false, GDMLT auto)")
        ->check(CLI::IsMember({"true", "false", "auto"}));
    render_cmd->add_option("--reconstruct", render.reconstruct_method,
                           "Gradient domain: l1 | l2 | cv (l1)");
    render_cmd
        ->add_option("--alpha", render.alpha,
                     "Gradient domain: weight of the primal (gdpt 0.2, gdmlt 0.05)")
        ->check(finite_number());
    render_cmd
        ->add_option("--coarse-radius", render.coarse_radius,
                     "Gradient domain: restore the primal's scales beyond this many pixels "
                     "(energy; 0 = off, default 8)")
        ->check(CLI::Range(0, 4096));
    render_cmd
        ->add_option("--huber", render.huber,
                     "Gradient domain, l1: Huber threshold in noise standard deviations where the "
                     "render has variance layers (gdpt, gdmlt; 1.345; 0 = pure L1)")
        ->check(CLI::NonNegativeNumber)
        ->check(finite_number());
    render_cmd->add_option("--shift", render.shift,
                           "Gradient domain: auto | reconnect | halfvector | replay");
    render_cmd
        ->add_option("--primal-weight", render.primal_weight,
                     "GDMLT: weight w of the primal in the target sum|D| + w Y(C) (1)")
        ->check(finite_number());
    render_cmd
        ->add_option("--gdpt-share", render.gdpt_share,
                     "GDMLT: share of the budget for GDPT beside the chains, combined by "
                     "inverse variance: auto (a pilot of each decides) | 0 (chains only) .. 1 "
                     "(auto)")
        ->check(CLI::IsMember({"auto"}) | CLI::Range(0.0, 1.0));
    render_cmd->add_option("--primal-from-offsets", render.primal_from_offsets,
                           "GDMLT: primal also from the neighbours' offset paths (G-PT's MIS "
                           "between pixels): true | false");
    render_cmd->add_option("--normalise-link-count", render.normalise_link_count,
                           "GDMLT: weigh a pixel's differences in the target by its lattice "
                           "link count over its link count (ADAP): true | false (true)");
    render_cmd->add_option("--very-direct-samples", render.very_direct_samples,
                           "GDMLT: spp of the pass for emitters seen directly (64)");
    render_cmd
        ->add_option("--bootstrap-error", render.bootstrap_error,
                     "GDMLT: grow the bootstrap until b's relative standard error is "
                     "below this (0.01)")
        ->check(finite_number());

    render_cmd->add_flag(
        "--features", render.features,
        "Also render ADAP's feature images (albedo, normal, depth, shape_id and their "
        "variances) into layers of the EXR, before the render");
    render_cmd
        ->add_option("--feature-spp", render.feature_spp,
                     "Samples per pixel of the feature pass (--features, --neighbours adap; 4)")
        ->check(CLI::PositiveNumber);
    render_cmd->add_option("--neighbours", render.neighbours,
                           "Gradient domain: lattice | adap (feature-selected, Manzi et al. 2014)");
    render_cmd->add_option("--adap-k", render.adap_k,
                           "ADAP: most similar candidates each pixel keeps (4)");
    render_cmd->add_option("--adap-window", render.adap_window,
                           "ADAP: candidates within this many pixels on each axis (2)");
    render_cmd
        ->add_option("--adap-sigma", render.adap_sigma,
                     "ADAP: bandwidths albedo,normal,depth,shape (0.1,0.2,0.05,0.5; 0 = off)")
        ->delimiter(',')
        ->expected(4)
        ->check(finite_number());
    render_cmd->add_flag("--adap-mutual", render.adap_mutual,
                         "ADAP: keep an edge only when both ends chose it (default: either)");

    std::string info_scene;
    std::vector<std::string> info_defines;
    bool info_lenient = false;
    CLI::App* info_cmd = app.add_subcommand("info", "Print what a scene contains (JSON)");
    info_cmd->add_option("scene", info_scene, "Scene file")->required();
    info_cmd->add_option("-D,--define", info_defines, "Scene parameter name=value");
    info_cmd->add_flag("--lenient", info_lenient, "Unknown plugins/properties are warnings");

    add_reconstruct_command(app, exit_code);

    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        const int code = app.exit(e);
        return code == 0 ? 0 : 2;
    }

    try {
        if (render_cmd->parsed()) return run_render(render);
        if (info_cmd->parsed()) return run_info(info_scene, info_defines, info_lenient);
    } catch (const InputError& e) {
        std::cerr << e.what() << "\n";
        return 2;
    } catch (const OutputError& e) {
        std::cerr << "gdmlt: " << e.what() << "\n";
        return 1;
    } catch (const std::bad_alloc&) {
        std::cerr
            << "gdmlt: out of memory (a smaller film, crop window or fewer threads may fit)\n";
        return 1;
    } catch (const std::exception& e) {
        std::cerr << "gdmlt: internal error: " << e.what() << "\n";
        return 1;
    }
    return exit_code;
}
