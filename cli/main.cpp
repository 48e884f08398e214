// SPDX-License-Identifier: GPL-3.0-or-later
// The gdmlt command line: render, info, reconstruct. The only place that knows argv, output
// paths, signals and terminals.
#include <tbb/global_control.h>
#include <tbb/info.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>

#include "cli/progress.h"
#include "cli/reconstruct_command.h"
#include "core/image/image_io.h"
#include "core/render/render_path.h"
#include "core/scene/scene.h"
#include "core/scene/scene_desc.h"

namespace {

using namespace gdmlt;
using json = nlohmann::json;

constexpr const char* kVersion = "0.1.0";

std::atomic<bool> g_interrupted{false};  // set by SIGINT; the render polls it

extern "C" void on_sigint(int) {
    g_interrupted.store(true);
}

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
};

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

void write_text_atomically(const std::string& path, const std::string& text) {
    const std::filesystem::path target(path);
    if (target.has_parent_path()) std::filesystem::create_directories(target.parent_path());
    const std::string temp = path + ".tmp";
    {
        std::ofstream out(temp);
        out << text;
        if (!out) throw std::runtime_error("cannot write " + temp);
    }
    std::filesystem::rename(temp, target);
}

int run_render(const RenderOptions& options) {
    const Scene scene = load_scene(options.scene_path, options.defines, options.lenient);

    // Effective configuration: defaults < scene file < command line.
    const std::string integrator =
        options.integrator.empty() ? scene.integrator().type : options.integrator;
    if (integrator != "path")
        throw InputError("integrator '" + integrator + "' is not available yet (available: path)");
    RenderSettings settings;
    settings.spp = options.spp > 0 ? options.spp : scene.sampler().sample_count;
    settings.time_budget_s = options.time_s;
    if (options.time_s > 0.0 && options.spp == 0)
        settings.spp = std::numeric_limits<int>::max() / 2;
    settings.seed = options.seed.value_or(scene.sampler().seed);
    settings.path.max_depth = options.max_depth.value_or(scene.integrator().max_depth);
    settings.path.rr_depth = scene.integrator().rr_depth;
    settings.path.hide_emitters = scene.integrator().hide_emitters;
    if (settings.path.max_depth == 0 || settings.path.max_depth < -1)
        throw InputError("--max-depth must be -1 or at least 1");

    const int threads = options.threads > 0 ? options.threads : tbb::info::default_concurrency();
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                              static_cast<std::size_t>(threads));

    json config = {
        {"scene", options.scene_path},
        {"integrator", integrator},
        {"spp", options.time_s > 0.0 && options.spp == 0 ? json(nullptr) : json(settings.spp)},
        {"time_budget_s", settings.time_budget_s},
        {"seed", settings.seed},
        {"max_depth", settings.path.max_depth},
        {"rr_depth", settings.path.rr_depth},
        {"hide_emitters", settings.path.hide_emitters},
        {"threads", threads},
        {"defines", options.defines},
        {"version", kVersion}};

    const Film& film = scene.camera().film();
    if (!options.quiet)
        std::cerr << "gdmlt: rendering " << options.scene_path << " (" << film.crop_width << "x"
                  << film.crop_height << ", " << integrator << ", "
                  << (options.time_s > 0.0 ? std::to_string(options.time_s) + " s"
                                           : std::to_string(settings.spp) + " spp")
                  << ", " << threads << " threads, seed " << settings.seed << ")\n";

    g_interrupted.store(false);
    std::signal(SIGINT, on_sigint);
    ProgressBar bar(isatty(STDERR_FILENO) != 0, options.quiet);
    const RenderOutput out = render_path(
        scene, settings, &g_interrupted,
        [&](const RenderProgress& p) { bar.update(p.fraction, p.samples, p.elapsed_s); });
    std::signal(SIGINT, SIG_DFL);
    bar.finish(out.stats.interrupted);

    const RenderStats& s = out.stats;
    json stats = {
        {"config", config},
        {"partial", s.interrupted},
        {"render_s", s.render_s},
        {"samples", s.samples},
        {"spp_completed", s.spp_completed},
        {"passes", s.passes},
        {"samples_per_s", s.render_s > 0 ? static_cast<double>(s.samples) / s.render_s : 0.0},
        {"rays",
         {{"camera", s.counters.camera_rays},
          {"bounce", s.counters.bounce_rays},
          {"shadow", s.counters.shadow_rays},
          {"total", s.counters.rays()},
          {"per_s", s.render_s > 0 ? static_cast<double>(s.counters.rays()) / s.render_s : 0.0}}},
        {"nonfinite_samples_dropped", s.nonfinite_samples_dropped},
        {"scene", {{"features", features_json(scene.features())}, {"counts", scene.counts()}}},
        {"machinery",
         {{"next_event_estimation", true},
          {"manifold_solver", false},
          {"why_manifold_off", "the path integrator never uses it"}}}};

    ExrAttributes attributes;
    attributes["gdmlt/config"] = config.dump();
    attributes["gdmlt/seed"] = std::to_string(settings.seed);
    attributes["gdmlt/version"] = kVersion;
    attributes["gdmlt/partial"] = s.interrupted ? "true" : "false";
    attributes["gdmlt/spp_completed"] = std::to_string(s.spp_completed);

    std::string output = options.output;
    if (output.empty()) output = std::filesystem::path(options.scene_path).stem().string() + ".exr";
    write_exr(output, {ExrLayer{"", {"R", "G", "B"}, out.image}}, attributes);
    const std::string png = std::filesystem::path(output).replace_extension(".png").string();
    write_png_srgb(png, out.image);
    if (!options.stats_path.empty())
        write_text_atomically(options.stats_path, stats.dump(2) + "\n");

    if (!options.quiet)
        std::cerr << "gdmlt: wrote " << output << " and " << png
                  << (s.interrupted ? " (partial: interrupted)" : "") << "; " << s.samples
                  << " samples in " << s.render_s << " s ("
                  << (s.render_s > 0 ? static_cast<double>(s.samples) / s.render_s / 1e6 : 0.0)
                  << " M samples/s)\n";
    return s.interrupted ? 130 : 0;
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
    render_cmd->add_option("--integrator", render.integrator, "path (default: the scene's)");
    auto* spp_opt =
        render_cmd->add_option("--spp", render.spp, "Samples per pixel (default: the scene's)")
            ->check(CLI::PositiveNumber);
    render_cmd
        ->add_option("--time", render.time_s,
                     "Time budget in seconds (with --spp: whichever ends first)")
        ->check(CLI::PositiveNumber);
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
        std::cerr << "gdmlt: error: " << e.what() << "\n";
        return 2;
    } catch (const std::exception& e) {
        std::cerr << "gdmlt: internal error: " << e.what() << "\n";
        return 1;
    }
    return exit_code;
}
