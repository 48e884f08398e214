// SPDX-License-Identifier: GPL-3.0-or-later
#include "cli/reconstruct_command.h"

#include <tbb/global_control.h>

#include <cstdio>
#include <filesystem>
#include <iostream>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "cli/validators.h"
#include "core/camera/pixel_filter.h"
#include "core/image/gradient_buffers.h"
#include "core/image/gradient_layers.h"
#include "core/image/image_io.h"
#include "core/scene/scene_desc.h"
#include "reconstruct/reconstruct.h"

namespace gdmlt {
namespace {

struct ReconstructOptions {
    std::string input;
    std::string output;
    std::string method;                // empty: the render's (EXR header), else l1
    std::optional<double> alpha;       // unset: the render's, else 0.2
    std::optional<int> coarse_radius;  // unset: the render's, else kDefaultCoarseRadius
    std::optional<double> huber;       // unset: the render's, else 0 (pure L1)
    int iterations = 0;                // 0 = the method's default
    double tolerance = 0.0;            // 0 = the method's default
    int threads = 0;
    float exposure = 0.f;
    bool quiet = false;
};

GradientBuffers read_buffers(const std::string& path, ExrAttributes& attributes) {
    return gradient_buffers_from_layers(read_exr(path, &attributes), path);
}

std::string default_output(const std::string& input) {
    std::filesystem::path p(input);
    p.replace_filename(p.stem().string() + "_final.exr");
    return p.string();
}

/// The reconstruction method and alpha the render used (its "gdmlt/config" header), so that
/// `gdmlt reconstruct raw.exr` without flags reproduces the render's final image.
void defaults_from_header(const ExrAttributes& attributes, ReconstructOptions& o) {
    const auto config = attributes.find("gdmlt/config");
    if (config == attributes.end()) return;
    const nlohmann::json j = nlohmann::json::parse(config->second, nullptr, false);
    if (!j.is_object()) return;
    if (o.method.empty() && j.contains("reconstruct") && j["reconstruct"].is_string())
        o.method = j["reconstruct"].get<std::string>();
    if (!o.alpha && j.contains("alpha") && j["alpha"].is_number())
        o.alpha = j["alpha"].get<double>();
    if (!o.coarse_radius && j.contains("coarse_radius") && j["coarse_radius"].is_number_integer())
        o.coarse_radius = j["coarse_radius"].get<int>();
    if (!o.huber && j.contains("huber") && j["huber"].is_number())
        o.huber = j["huber"].get<double>();
}

/// The film filter a gradient-domain render applied to its reconstructed image (its
/// "gdmlt/config" header's film_filter), applied again here; the box filter otherwise.
PixelFilter film_filter_from_header(const ExrAttributes& attributes) {
    const auto config = attributes.find("gdmlt/config");
    if (config == attributes.end()) return {};
    const nlohmann::json j = nlohmann::json::parse(config->second, nullptr, false);
    if (!j.is_object() || !j.contains("film_filter") || !j["film_filter"].is_object()) return {};
    const nlohmann::json& f = j["film_filter"];
    const std::string applied = f.value("applied", "");
    if (applied.rfind("image convolution", 0) != 0) return {};
    const std::string name = f.value("name", "box");
    const double radius = f.value("radius", 0.0);
    try {
        if (name == "gaussian") return PixelFilter::gaussian(static_cast<float>(radius / 4.0));
        if (name == "tent") return PixelFilter::tent(static_cast<float>(radius));
    } catch (const std::invalid_argument& e) {
        throw InputError(std::string("film_filter in the header: ") + e.what());
    }
    return {};
}

int run_reconstruct(ReconstructOptions o) {
    std::unique_ptr<tbb::global_control> limit;
    if (o.threads > 0)
        limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                      static_cast<std::size_t>(o.threads));

    // The outputs are checked before the solve; overwriting the input would lose the raw layers.
    const std::string output = o.output.empty() ? default_output(o.input) : o.output;
    const std::string png = std::filesystem::path(output).replace_extension(".png").string();
    for (const std::string& path : {output, png}) {
        check_output_path(path, "-o");
        if (same_file(path, o.input)) throw InputError("-o '" + path + "' is the input file");
    }
    ExrAttributes attributes;
    const GradientBuffers buffers = read_buffers(o.input, attributes);
    defaults_from_header(attributes, o);
    if (o.method.empty()) o.method = "l1";
    const std::optional<reconstruct::Method> method = reconstruct::parse_method(o.method);
    if (!method) throw InputError("--method must be l1, l2 or cv, got '" + o.method + "'");
    if (!o.alpha) o.alpha = 0.2;

    reconstruct::ReconstructConfig config;
    config.method = *method;
    config.alpha = *o.alpha;
    config.coarse_radius = o.coarse_radius.value_or(reconstruct::kDefaultCoarseRadius);
    if (config.coarse_radius < 0) throw InputError("--coarse-radius must not be negative");
    config.huber_k = o.huber.value_or(0.0);
    if (o.iterations > 0) {
        switch (*method) {
            case reconstruct::Method::l2:
                config.cg_max_iterations = o.iterations;
                break;
            case reconstruct::Method::l1:
                config.irls_iterations = o.iterations;
                break;
            case reconstruct::Method::cv:
                config.cv_iterations = o.iterations;
                break;
        }
    }
    if (o.tolerance > 0.0) {
        config.cg_tolerance = o.tolerance;
        config.irls_cg_tolerance = o.tolerance;
    }
    reconstruct::ReconstructResult result;
    try {
        result = reconstruct::reconstruct_buffers(buffers, config);
    } catch (const std::invalid_argument& e) {
        throw InputError(o.input + ": " + e.what());
    }
    const PixelFilter film_filter = film_filter_from_header(attributes);
    result.image = filter_image(result.image, film_filter);
    const reconstruct::ReconstructStats& s = result.stats;

    attributes["gdmlt.reconstruct.method"] = o.method;
    attributes["gdmlt.reconstruct.alpha"] = std::to_string(*o.alpha);
    attributes["gdmlt.reconstruct.coarse_radius"] = std::to_string(config.coarse_radius);
    attributes["gdmlt.reconstruct.huber"] = std::to_string(config.huber_k);
    attributes["gdmlt.reconstruct.film_filter"] = film_filter.name();
    attributes["gdmlt.reconstruct.iterations"] = std::to_string(s.iterations);
    attributes["gdmlt.reconstruct.cg_iterations"] = std::to_string(s.cg_iterations);
    attributes["gdmlt.reconstruct.relative_residual"] = std::to_string(s.final_relative_residual);
    attributes["gdmlt.reconstruct.dropped_edges"] =
        std::to_string(s.dropped_nonfinite_edges + s.dropped_negative_weight_edges);
    OutputFiles files;  // all or nothing, as a render's
    files.add_png_srgb(png, result.image, o.exposure);
    files.add_exr(output, {{"", {"R", "G", "B"}, result.image}}, attributes);
    files.commit();

    if (!o.quiet) {
        std::fprintf(
            stderr,
            "reconstruct %s: %d iterations (%d CG), relative residual %.3g, "
            "%lld edges dropped, %lld missing primal pixels, %.3f s (setup %.3f s) -> %s\n",
            o.method.c_str(), s.iterations, s.cg_iterations, s.final_relative_residual,
            static_cast<long long>(s.dropped_nonfinite_edges + s.dropped_negative_weight_edges),
            static_cast<long long>(s.missing_primal_pixels), s.seconds_total, s.seconds_setup,
            output.c_str());
    }
    return 0;
}

}  // namespace

void add_reconstruct_command(CLI::App& app, int& exit_code) {
    auto options = std::make_shared<ReconstructOptions>();
    CLI::App* cmd = app.add_subcommand(
        "reconstruct",
        "Reconstruct a gradient-domain render (layers primal, dx, dy) with L1, L2 "
        "screened Poisson or weighted control variates");
    cmd->add_option("input", options->input, "Raw EXR with layers primal, dx, dy")->required();
    cmd->add_option("-o,--output", options->output,
                    "Output EXR (default: <input>_final.exr; a PNG preview is written beside it)");
    cmd->add_option("--method", options->method, "l1, l2 or cv (default: the render's, else l1)")
        ->check(CLI::IsMember({"l1", "l2", "cv"}));
    cmd->add_option("--alpha", options->alpha,
                    "Screening weight of the primal (default: the render's, else 0.2)")
        ->check(CLI::NonNegativeNumber)
        ->check(finite_number());
    cmd->add_option("--coarse-radius", options->coarse_radius,
                    "Restore the primal's scales beyond this many pixels (default: the render's, "
                    "else 8; 0 = off)");
    cmd->add_option("--huber", options->huber,
                    "l1: Huber threshold in noise standard deviations where variance layers "
                    "exist (default: the render's, else 0 = pure L1)")
        ->check(CLI::NonNegativeNumber)
        ->check(finite_number());
    cmd->add_option("--iterations", options->iterations,
                    "l2: max CG iterations, l1: IRLS iterations, cv: iterations")
        ->check(CLI::PositiveNumber);
    cmd->add_option("--tolerance", options->tolerance, "CG relative residual (default 1e-3)")
        ->check(CLI::PositiveNumber)
        ->check(finite_number());
    cmd->add_option("-t,--threads", options->threads, "Threads (default: all cores)")
        ->check(CLI::NonNegativeNumber);
    cmd->add_option("--exposure", options->exposure, "PNG preview exposure in stops")
        ->check(finite_number());
    cmd->add_flag("-q,--quiet", options->quiet, "No summary line");
    cmd->callback([options, &exit_code] {
        try {
            exit_code = run_reconstruct(*options);
        } catch (const InputError& e) {
            std::cerr << "gdmlt: error: " << e.what() << "\n";
            exit_code = 2;
        } catch (const OutputError& e) {
            std::cerr << "gdmlt: " << e.what() << "\n";
            exit_code = 1;
        } catch (const std::exception& e) {
            std::cerr << "gdmlt: internal error: " << e.what() << "\n";
            exit_code = 1;
        }
    });
}

}  // namespace gdmlt
