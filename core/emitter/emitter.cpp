// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/emitter/emitter.h"

#include <stdexcept>

#include "core/math/trig.h"

namespace gdmlt {

const char* emitter_kind_name(const Emitter& e) {
    if (std::holds_alternative<AreaEmitter>(e)) return "area";
    if (std::holds_alternative<PointEmitter>(e)) return "point";
    if (std::holds_alternative<SpotEmitter>(e)) return "spot";
    if (std::holds_alternative<DirectionalEmitter>(e)) return "directional";
    if (std::holds_alternative<EnvmapEmitter>(e)) return "envmap";
    if (std::holds_alternative<ProjectorEmitter>(e)) return "projector";
    return "constant";
}

SpotEmitter make_spot(const Vec3f& position, const Mat3f& world_from_local, const Rgb& intensity,
                      float cutoff_deg, float beam_width_deg, std::optional<RgbTexture> texture) {
    SpotEmitter s;
    s.position = position;
    s.local_from_world = world_from_local.transpose();
    s.intensity = intensity;
    s.cutoff_rad = degrees_to_radians(cutoff_deg);
    // A beam as wide as the cutoff would divide by zero in the falloff: keep a sliver.
    s.beam_width_rad = std::min(degrees_to_radians(beam_width_deg), s.cutoff_rad * (1.f - 1e-6f));
    s.cos_cutoff = std::cos(s.cutoff_rad);
    s.cos_beam_width = std::cos(s.beam_width_rad);
    s.tan_cutoff = std::tan(s.cutoff_rad);
    if (texture) {
        s.textured = true;
        s.texture = std::move(*texture);
    }
    return s;
}

namespace {

/// Local direction of lat-long coordinates (the inverse of envmap_uv): theta = pi v,
/// phi = 2 pi u.
Vec3f envmap_direction(const Vec2f& uv, float* sin_theta) {
    float sin_phi = 0.f, cos_phi = 1.f, cos_theta = 1.f;
    sincos_turns(uv.x(), sin_phi, cos_phi);
    sincos_turns(0.5f * uv.y(), *sin_theta, cos_theta);
    return {sin_phi * *sin_theta, cos_theta, -cos_phi * *sin_theta};
}

/// (u, v) of a local direction whose distance from the y axis is `sin_theta`. theta comes from
/// atan2(sin, cos) rather than acos(d.y): the same routine as phi, and accurate at the poles.
Vec2f envmap_uv(const Vec3f& d, float sin_theta) {
    float u = atan2_approx(d.x(), -d.z()) * (0.5f * kInvPi);
    if (u < 0.f) u += 1.f;
    const float v = atan2_approx(sin_theta, d.y()) * kInvPi;
    return {std::min(u, 0x1.fffffep-1f), std::clamp(v, 0.f, 1.f)};
}

float sin_theta_of(const Vec3f& d) {
    return std::sqrt(d.x() * d.x() + d.z() * d.z());
}

}  // namespace

Rgb EnvmapData::lookup(const Vec2f& uv) const {
    // Columns are periodic and centred at (i + 0.5) / width; rows run pole to pole.
    const auto w = static_cast<float>(width);
    float x = uv.x() * w - 0.5f;
    // u in [0, 1] (every caller here) puts x in [-0.5, width - 0.5]: one wrap of the left
    // half-column, without the division and floor of the general case below.
    if (x < 0.f) x += w;
    if (!(x >= 0.f && x < w)) x -= w * std::floor(x / w);
    const int x0 = std::clamp(static_cast<int>(x), 0, width - 1);
    const float fx = std::clamp(x - static_cast<float>(x0), 0.f, 1.f);
    const float y = std::clamp(uv.y(), 0.f, 1.f) * static_cast<float>(height - 1);
    const int y0 = std::min(static_cast<int>(y), height - 2);
    const float fy = std::clamp(y - static_cast<float>(y0), 0.f, 1.f);
    const std::size_t stride = static_cast<std::size_t>(width) + 1;
    const Eigen::Array4f* row0 =
        padded_rows.data() + static_cast<std::size_t>(y0) * stride + static_cast<std::size_t>(x0);
    const Eigen::Array4f* row1 = row0 + stride;
    const Eigen::Array4f value = (1.f - fy) * ((1.f - fx) * row0[0] + fx * row0[1]) +
                                 fy * ((1.f - fx) * row1[0] + fx * row1[1]);
    return value.head<3>();
}

EnvmapData make_envmap_data(int width, int height, std::vector<Rgb> texels) {
    if (width < 2 || height < 3 ||
        texels.size() != static_cast<std::size_t>(width) * static_cast<std::size_t>(height))
        throw std::invalid_argument("environment map must be at least 2 x 3 pixels");
    EnvmapData d;
    d.width = width;
    d.height = height;
    for (Rgb& t : texels)
        t = t.max(0.f).unaryExpr([](float v) { return std::isfinite(v) ? v : 0.f; });
    d.padded_rows.reserve(static_cast<std::size_t>(width + 1) * static_cast<std::size_t>(height));
    for (int j = 0; j < height; ++j) {
        const Rgb* row =
            texels.data() + static_cast<std::size_t>(j) * static_cast<std::size_t>(width);
        for (int i = 0; i <= width; ++i) {
            const Rgb& t = row[i < width ? i : 0];
            d.padded_rows.emplace_back(t.x(), t.y(), t.z(), 0.f);
        }
    }

    // Sampling cells: a width x height grid over (u, v). The bilinear radiance is largest at
    // the corners of the pieces the cell overlaps, so the maximum over these u and v positions
    // is the exact maximum over the cell: no cell with light gets zero probability.
    std::vector<float> weights(texels.size(), 0.f);
    double integral = 0.0;
    std::vector<float> vs;
    for (int j = 0; j < height; ++j) {
        const float v0 = static_cast<float>(j) / static_cast<float>(height);
        const float v1 = static_cast<float>(j + 1) / static_cast<float>(height);
        vs.assign({v0, v1});
        for (int k = 0; k < height; ++k) {
            const float vk = static_cast<float>(k) / static_cast<float>(height - 1);
            if (vk > v0 && vk < v1) vs.push_back(vk);
        }
        // Mean of sin(theta) over the cell's rows, and the cell's solid angle per unit u.
        const float band = std::cos(kPi * v0) - std::cos(kPi * v1);
        const float mean_sin = band / (kPi * (v1 - v0));
        for (int i = 0; i < width; ++i) {
            const float u0 = static_cast<float>(i) / static_cast<float>(width);
            const float u1 = static_cast<float>(i + 1) / static_cast<float>(width);
            const float um = 0.5f * (u0 + u1);
            float max_luminance = 0.f;
            for (float u : {u0, um, u1})
                for (float v : vs)
                    max_luminance = std::max(max_luminance, luminance(d.lookup({u, v})));
            weights[static_cast<std::size_t>(j) * static_cast<std::size_t>(width) +
                    static_cast<std::size_t>(i)] = max_luminance * mean_sin;
            integral += static_cast<double>(luminance(d.lookup({um, 0.5f * (v0 + v1)}))) *
                        (2.0 * std::numbers::pi / width) * band;
        }
    }
    d.distribution = Distribution2D(weights, width, height);
    d.luminance_integral = static_cast<float>(integral);
    return d;
}

Rgb EnvmapEmitter::eval(const Vec3f& d_world) const {
    const Vec3f d = local_from_world * d_world;
    return radiance_at(envmap_uv(d, sin_theta_of(d)));
}

EnvmapEmitter::Sample EnvmapEmitter::sample_direction(const Vec2f& u) const {
    Sample s;
    if (!data->distribution.valid()) return s;
    float pdf_uv = 0.f;
    s.uv = data->distribution.sample(u, &pdf_uv);
    float sin_theta = 0.f;
    const Vec3f d = envmap_direction(s.uv, &sin_theta);
    // d omega = 2 pi^2 sin(theta) du dv.
    if (!(sin_theta > 0.f) || !(pdf_uv > 0.f)) return s;
    // One reciprocal square root for the three components (Eigen's normalized() divides each
    // by the norm: its three divisions were the slowest instructions of this function, perf).
    const Vec3f rotated = world_from_local * d;
    s.direction = rotated * (1.f / std::sqrt(rotated.squaredNorm()));
    s.pdf_solid_angle = pdf_uv / (2.f * kPi * kPi * sin_theta);
    return s;
}

EnvmapEmitter::Sample EnvmapEmitter::sample(const Vec2f& u) const {
    Sample s = sample_direction(u);
    if (s.pdf_solid_angle > 0.f) s.radiance = radiance_at(s.uv);
    return s;
}

float EnvmapEmitter::pdf_solid_angle(const Vec3f& d_world) const {
    return eval_with_pdf(d_world).pdf_solid_angle;
}

EnvmapEmitter::Value EnvmapEmitter::eval_with_pdf(const Vec3f& d_world) const {
    const Vec3f d = local_from_world * d_world;
    const float sin_theta = sin_theta_of(d);
    const Vec2f uv = envmap_uv(d, sin_theta);
    Value v;
    v.radiance = radiance_at(uv);
    if (sin_theta > 0.f)
        v.pdf_solid_angle = data->distribution.pdf_area(uv) / (2.f * kPi * kPi * sin_theta);
    return v;
}

}  // namespace gdmlt
