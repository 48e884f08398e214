// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/texture/texture.h"

#include <stdexcept>

#include "core/image/image_io.h"

namespace gdmlt {
namespace {

int wrap_index(int i, int n, WrapMode mode) {
    switch (mode) {
        case WrapMode::Repeat: {
            const int r = i % n;
            return r < 0 ? r + n : r;
        }
        case WrapMode::Mirror: {
            // Period 2n: 0..n-1 forwards, then n-1..0 backwards.
            int r = i % (2 * n);
            if (r < 0) r += 2 * n;
            return r < n ? r : 2 * n - 1 - r;
        }
        case WrapMode::Clamp:
            return std::clamp(i, 0, n - 1);
    }
    return 0;
}

}  // namespace

BitmapData make_bitmap_data(int width, int height, std::vector<Rgb> texels, std::string filename) {
    if (width < 1 || height < 1 ||
        texels.size() != static_cast<std::size_t>(width) * static_cast<std::size_t>(height))
        throw std::invalid_argument("bitmap: empty image or texel count mismatch");
    BitmapData d;
    d.width = width;
    d.height = height;
    d.texels = std::move(texels);
    d.filename = std::move(filename);
    RgbD sum = RgbD::Zero();
    d.max = d.texels.front();
    d.min_luminance = d.max_luminance = luminance(d.texels.front());
    for (const Rgb& t : d.texels) {
        sum += t.cast<double>();
        d.max = d.max.max(t);
        const float l = luminance(t);
        d.min_luminance = std::min(d.min_luminance, l);
        d.max_luminance = std::max(d.max_luminance, l);
    }
    d.mean = (sum / static_cast<double>(d.texels.size())).cast<float>();
    return d;
}

BitmapData load_bitmap(const std::string& path, bool raw) {
    ImageFileInfo info;
    const Image image = read_image(path, &info);
    const bool linearise = info.integer_format && !raw;
    std::vector<Rgb> texels(image.pixel_count());
    for (int y = 0; y < image.height; ++y)
        for (int x = 0; x < image.width; ++x) {
            Rgb v;
            if (image.channels >= 3)
                v = Rgb(image(x, y, 0), image(x, y, 1), image(x, y, 2));
            else
                v = Rgb::Constant(image(x, y, 0));  // grey, or grey + alpha
            if (linearise)
                for (int c = 0; c < 3; ++c) v[c] = srgb_to_linear(v[c]);
            texels[static_cast<std::size_t>(y) * static_cast<std::size_t>(image.width) +
                   static_cast<std::size_t>(x)] = v;
        }
    return make_bitmap_data(image.width, image.height, std::move(texels), path);
}

Vec2f BitmapTexture::gradient(const Vec2f& uv_surface) const {
    const BitmapData& d = *data;
    const Vec2f uv = to_uv.apply(uv_surface);
    if (filter == FilterMode::Nearest || !uv.allFinite()) return Vec2f::Zero();
    const float x = uv.x() * static_cast<float>(d.width) - 0.5f;
    const float y = uv.y() * static_cast<float>(d.height) - 0.5f;
    const float x0f = std::floor(x), y0f = std::floor(y);
    const float fx = x - x0f, fy = y - y0f;
    const int x0 = static_cast<int>(x0f), y0 = static_cast<int>(y0f);
    const int xa = wrap_index(x0, d.width, wrap), xb = wrap_index(x0 + 1, d.width, wrap);
    const int ya = wrap_index(y0, d.height, wrap), yb = wrap_index(y0 + 1, d.height, wrap);
    const float f00 = luminance(d.texel(xa, ya)), f10 = luminance(d.texel(xb, ya));
    const float f01 = luminance(d.texel(xa, yb)), f11 = luminance(d.texel(xb, yb));
    // Partials in texel units, to the transformed uv by the resolution, then to surface uv
    // through to_uv's transpose (the chain rule). Mitsuba 3 (src/textures/bitmap.cpp,
    // eval_1_grad) scales by the resolution after the transpose, which agrees unless to_uv
    // mixes u and v on a non-square image.
    const float df_x = static_cast<float>(d.width) * ((1.f - fy) * (f10 - f00) + fy * (f11 - f01));
    const float df_y = static_cast<float>(d.height) * ((1.f - fx) * (f01 - f00) + fx * (f11 - f10));
    const Eigen::Matrix2f& m = to_uv.linear;
    return {m(0, 0) * df_x + m(1, 0) * df_y, m(0, 1) * df_x + m(1, 1) * df_y};
}

Rgb BitmapTexture::eval(const Vec2f& uv_surface) const {
    const BitmapData& d = *data;
    const Vec2f uv = to_uv.apply(uv_surface);
    if (!uv.allFinite()) return Rgb::Zero();
    if (filter == FilterMode::Nearest) {
        const int x = wrap_index(static_cast<int>(std::floor(uv.x() * static_cast<float>(d.width))),
                                 d.width, wrap);
        const int y = wrap_index(
            static_cast<int>(std::floor(uv.y() * static_cast<float>(d.height))), d.height, wrap);
        return d.texel(x, y);
    }
    // Texel centres sit at half-integer positions.
    const float x = uv.x() * static_cast<float>(d.width) - 0.5f;
    const float y = uv.y() * static_cast<float>(d.height) - 0.5f;
    const float x0f = std::floor(x), y0f = std::floor(y);
    const float fx = x - x0f, fy = y - y0f;
    const int x0 = static_cast<int>(x0f), y0 = static_cast<int>(y0f);
    // Both neighbours inside the image (every wrap mode leaves them be): no wrap_index, whose
    // integer divisions made this function 5% of the path tracer's time on a textured floor
    // (perf, materials_envmap).
    const auto inside = [](int i, int n) {
        return static_cast<unsigned>(i) < static_cast<unsigned>(n - 1);
    };
    const bool x_inside = inside(x0, d.width), y_inside = inside(y0, d.height);
    const int xa = x_inside ? x0 : wrap_index(x0, d.width, wrap);
    const int xb = x_inside ? x0 + 1 : wrap_index(x0 + 1, d.width, wrap);
    const int ya = y_inside ? y0 : wrap_index(y0, d.height, wrap);
    const int yb = y_inside ? y0 + 1 : wrap_index(y0 + 1, d.height, wrap);
    return (1.f - fy) * ((1.f - fx) * d.texel(xa, ya) + fx * d.texel(xb, ya)) +
           fy * ((1.f - fx) * d.texel(xa, yb) + fx * d.texel(xb, yb));
}

std::pair<float, float> MeshAttributeTexture::range() const {
    float lo = kInfinity, hi = -kInfinity;
    for (const auto& attribute : binding->by_shape)
        if (attribute)
            for (const float v : attribute->values) {
                lo = std::min(lo, v * scale);
                hi = std::max(hi, v * scale);
            }
    if (!(lo <= hi)) return {0.f, 1.f};
    return {lo, hi};
}

Rgb MeshAttributeTexture::mean() const {
    // The mean of the stored values (per triangle, not per area: this weighs lobes and
    // classifies, it is not an integral).
    Rgb sum = Rgb::Zero();
    double count = 0.0;
    for (const auto& attribute : binding->by_shape) {
        if (!attribute) continue;
        const auto d = static_cast<std::size_t>(attribute->dim);
        for (std::size_t i = 0; i + d <= attribute->values.size(); i += d) {
            for (std::size_t c = 0; c < 3; ++c)
                sum[static_cast<int>(c)] += attribute->values[i + (d == 1 ? 0 : c)];
            count += 1.0;
        }
    }
    if (count == 0.0) return Rgb::Constant(0.5f);
    return sum * (scale / static_cast<float>(count));
}

Rgb RgbTexture::max_value() const {
    if (const auto* c = std::get_if<ConstantTexture>(&texture_)) return c->value;
    if (const auto* b = std::get_if<BitmapTexture>(&texture_)) return b->data->max;
    if (const auto* m = std::get_if<MeshAttributeTexture>(&texture_))
        return Rgb::Constant(m->range().second);
    const auto& k = std::get<CheckerboardTexture>(texture_);
    return k.color0.max(k.color1);
}

Rgb RgbTexture::mean_value() const {
    if (const auto* c = std::get_if<ConstantTexture>(&texture_)) return c->value;
    if (const auto* b = std::get_if<BitmapTexture>(&texture_)) return b->data->mean;
    if (const auto* m = std::get_if<MeshAttributeTexture>(&texture_)) return m->mean();
    const auto& k = std::get<CheckerboardTexture>(texture_);
    return 0.5f * (k.color0 + k.color1);
}

// A mesh attribute's luminance bounds are its channels' bounds (luminance weighs channels by
// weights that sum to one).
float RgbTexture::min_luminance() const {
    if (const auto* c = std::get_if<ConstantTexture>(&texture_)) return luminance(c->value);
    if (const auto* b = std::get_if<BitmapTexture>(&texture_)) return b->data->min_luminance;
    if (const auto* m = std::get_if<MeshAttributeTexture>(&texture_)) return m->range().first;
    const auto& k = std::get<CheckerboardTexture>(texture_);
    return std::min(luminance(k.color0), luminance(k.color1));
}

float RgbTexture::max_luminance() const {
    if (const auto* c = std::get_if<ConstantTexture>(&texture_)) return luminance(c->value);
    if (const auto* b = std::get_if<BitmapTexture>(&texture_)) return b->data->max_luminance;
    if (const auto* m = std::get_if<MeshAttributeTexture>(&texture_)) return m->range().second;
    const auto& k = std::get<CheckerboardTexture>(texture_);
    return std::max(luminance(k.color0), luminance(k.color1));
}

}  // namespace gdmlt
