// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Spatially varying parameters (reflectance, radiance, roughness). A closed set of value types:
// constants, bitmaps, checkerboards and mesh attributes, with Mitsuba 3's `bitmap`,
// `checkerboard` and `mesh_attribute` meanings:
//  - texture space: (u, v) with v = 0 at the first (top) row of the image file, repeated
//    outside [0, 1)^2 unless `wrap_mode` says otherwise;
//  - bilinear filtering treats texel (i, j) as the value at ((i + 0.5) / width,
//    (j + 0.5) / height);
//  - 8- and 16-bit files hold sRGB-encoded values and are linearised at load unless `raw`;
//    float files (EXR, HDR) are linear already;
//  - `to_uv` is an affine map applied to the surface's uv before the lookup.
// Image data is immutable after loading and shared between copies (std::shared_ptr<const>),
// so textures stay cheap to copy and evaluation never allocates.
#include <memory>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "core/math/types.h"
#include "core/texture/texture_point.h"

namespace gdmlt {

/// Affine map of texture coordinates (Mitsuba's `to_uv`): uv' = linear * uv + offset.
struct UvTransform {
    Eigen::Matrix2f linear = Eigen::Matrix2f::Identity();
    Vec2f offset = Vec2f::Zero();
    Vec2f apply(const Vec2f& uv) const { return linear * uv + offset; }
};

enum class WrapMode { Repeat, Mirror, Clamp };
enum class FilterMode { Bilinear, Nearest };

/// Linear RGB texels, row-major, row 0 at v = 0; with summary values for light power, sampling
/// weights and roughness classification.
struct BitmapData {
    int width = 0;
    int height = 0;
    std::vector<Rgb> texels;
    Rgb mean = Rgb::Zero();
    Rgb max = Rgb::Zero();
    float min_luminance = 0.f;
    float max_luminance = 0.f;
    std::string filename;

    const Rgb& texel(int x, int y) const {
        return texels[static_cast<std::size_t>(y) * static_cast<std::size_t>(width) +
                      static_cast<std::size_t>(x)];
    }
};

/// Builds BitmapData from linear texels (fills the summaries). Throws std::invalid_argument on
/// an empty image or a size mismatch.
BitmapData make_bitmap_data(int width, int height, std::vector<Rgb> texels, std::string filename);

/// Loads an image file through core/image (OpenImageIO) as linear RGB: one channel is
/// replicated to grey, alpha is dropped, integer formats are linearised from sRGB unless
/// `raw`. Throws InputError naming the file on failure.
BitmapData load_bitmap(const std::string& path, bool raw);

struct ConstantTexture {
    Rgb value = Rgb::Zero();
};

struct BitmapTexture {
    std::shared_ptr<const BitmapData> data;
    UvTransform to_uv;
    WrapMode wrap = WrapMode::Repeat;
    FilterMode filter = FilterMode::Bilinear;

    Rgb eval(const Vec2f& uv) const;
    /// Mitsuba 3's eval_1_grad: the gradient in surface uv of the bilinear interpolation of
    /// the texels' luminances (zero with nearest filtering), through to_uv by the chain rule.
    Vec2f gradient(const Vec2f& uv) const;
};

/// Mitsuba's checkerboard: color0 where floor(2u) and floor(2v) have the same parity (the
/// squares containing uv = (0.25, 0.25) and (0.75, 0.75)), color1 elsewhere.
struct CheckerboardTexture {
    Rgb color0 = Rgb::Constant(0.4f);
    Rgb color1 = Rgb::Constant(0.2f);
    UvTransform to_uv;

    Rgb eval(const Vec2f& uv) const {
        const Vec2f p = to_uv.apply(uv);
        const float fu = p.x() - std::floor(p.x()), fv = p.y() - std::floor(p.y());
        return (fu < 0.5f) == (fv < 0.5f) ? color0 : color1;
    }
};

/// Which attribute a mesh_attribute texture reads on each shape (by shape index; null where
/// the shape has none): filled by the scene builder once the shapes are built.
struct MeshAttributeBinding {
    std::vector<std::shared_ptr<const MeshAttribute>> by_shape;
};

/// Mitsuba 3's `mesh_attribute`: a PLY mesh's `vertex_*` (interpolated) or `face_*` values
/// times `scale`, zero on shapes without the attribute.
struct MeshAttributeTexture {
    std::string name;
    float scale = 1.f;
    std::shared_ptr<MeshAttributeBinding> binding;

    Rgb eval(const TexturePoint& at) const {
        const auto shape = static_cast<std::size_t>(at.shape);
        if (at.shape < 0 || shape >= binding->by_shape.size() || !binding->by_shape[shape])
            return Rgb::Zero();
        return binding->by_shape[shape]->eval(at.primitive, at.barycentric) * scale;
    }
    /// Smallest and largest value over the bound attributes' channels ([0, 1] before any is
    /// bound: Mitsuba expects colours there).
    std::pair<float, float> range() const;
    Rgb mean() const;
};

using TextureModel =
    std::variant<ConstantTexture, BitmapTexture, CheckerboardTexture, MeshAttributeTexture>;

class RgbTexture {
  public:
    RgbTexture() = default;
    /// A constant; implicit so that `DiffuseBsdf{Rgb(0.5f, 0.5f, 0.5f)}` reads naturally.
    template <typename Derived>
    RgbTexture(const Eigen::ArrayBase<Derived>& constant)  // NOLINT: implicit on purpose
        : texture_(ConstantTexture{Rgb(constant)}) {}
    explicit RgbTexture(TextureModel texture) : texture_(std::move(texture)) {}

    Rgb eval(const TexturePoint& at) const {
        if (const auto* c = std::get_if<ConstantTexture>(&texture_)) return c->value;
        if (const auto* b = std::get_if<BitmapTexture>(&texture_)) return b->eval(at.uv);
        if (const auto* k = std::get_if<CheckerboardTexture>(&texture_)) return k->eval(at.uv);
        return std::get<MeshAttributeTexture>(texture_).eval(at);
    }
    /// The scalar value's gradient in uv (bump maps): bitmaps' (BitmapTexture::gradient), zero
    /// for the others (constant almost everywhere, or per face), as in Mitsuba 3.
    Vec2f gradient(const TexturePoint& at) const {
        if (const auto* b = std::get_if<BitmapTexture>(&texture_)) return b->gradient(at.uv);
        return Vec2f::Zero();
    }
    bool is_constant() const { return std::holds_alternative<ConstantTexture>(texture_); }
    /// Largest value per channel over the surface (for bounds).
    Rgb max_value() const;
    /// Mean value over texture space (for light power and lobe-selection weights, as
    /// Mitsuba's Texture::mean()).
    Rgb mean_value() const;
    /// Smallest and largest luminance over the surface (roughness classification).
    float min_luminance() const;
    float max_luminance() const;
    const TextureModel& model() const { return texture_; }

  private:
    TextureModel texture_;
};

/// A scalar parameter (roughness): a constant, or the luminance of an RGB texture (a
/// one-channel image is loaded as grey, whose luminance is its value).
class FloatTexture {
  public:
    FloatTexture() = default;
    FloatTexture(float constant) : constant_(constant) {}  // NOLINT: implicit on purpose
    explicit FloatTexture(RgbTexture texture)
        : texture_(as_scalar(std::move(texture))),
          constant_(0.f),
          is_constant_(texture_.is_constant()) {
        if (is_constant_) constant_ = luminance(texture_.eval(TexturePoint()));
    }

    float eval(const TexturePoint& at) const {
        return is_constant_ ? constant_ : luminance(texture_.eval(at));
    }
    bool is_constant() const { return is_constant_; }
    float min_value() const { return is_constant_ ? constant_ : texture_.min_luminance(); }
    float max_value() const { return is_constant_ ? constant_ : texture_.max_luminance(); }

  private:
    /// Mitsuba 3's checkerboard gives color0 where the two halves agree when evaluated as a
    /// colour (Checkerboard::eval) but where they differ when evaluated as a scalar (eval_1,
    /// as for roughness): a scalar checkerboard is its colour form with the colours swapped.
    static RgbTexture as_scalar(RgbTexture texture) {
        if (const auto* c = std::get_if<CheckerboardTexture>(&texture.model())) {
            CheckerboardTexture swapped = *c;
            std::swap(swapped.color0, swapped.color1);
            return RgbTexture(TextureModel(swapped));
        }
        return texture;
    }

    RgbTexture texture_;
    float constant_ = 0.f;
    bool is_constant_ = true;
};

}  // namespace gdmlt
