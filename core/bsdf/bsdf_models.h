// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Internal to core/bsdf: the per-model eval / pdf / sample functions that Bsdf dispatches to
// with std::visit (plain overloads, no virtual calls). Queries arrive in the model's own frame:
// for one-sided models wo is expected on the front (they return zero otherwise); transmissive
// models accept either side.
#include "core/bsdf/bsdf.h"

namespace gdmlt::detail {

/// Mirror reflection of `w` about the microfacet normal `m`.
inline Vec3f reflect_about(const Vec3f& w, const Vec3f& m) {
    return 2.f * w.dot(m) * m - w;
}

#define GDMLT_DECLARE_BSDF_MODEL(M)                                                            \
    Rgb eval_model(const M& m, const TexturePoint& at, const Vec3f& wo, const Vec3f& wi,       \
                   TransportMode mode);                                                        \
    float pdf_model(const M& m, const TexturePoint& at, const Vec3f& wo, const Vec3f& wi);     \
    BsdfSample sample_model(const M& m, const TexturePoint& at, const Vec3f& wo, float u_lobe, \
                            const Vec2f& u, TransportMode mode);                               \
    BsdfLobes model_lobes(const M& m);                                                         \
    RoughnessClass model_class_at(const M& m, const TexturePoint& at);                         \
    RoughnessClass model_class(const M& m);

GDMLT_DECLARE_BSDF_MODEL(DiffuseBsdf)
GDMLT_DECLARE_BSDF_MODEL(DielectricBsdf)
GDMLT_DECLARE_BSDF_MODEL(ThinDielectricBsdf)
GDMLT_DECLARE_BSDF_MODEL(ConductorBsdf)
GDMLT_DECLARE_BSDF_MODEL(RoughConductorBsdf)
GDMLT_DECLARE_BSDF_MODEL(RoughDielectricBsdf)
GDMLT_DECLARE_BSDF_MODEL(PlasticBsdf)
GDMLT_DECLARE_BSDF_MODEL(RoughPlasticBsdf)

#undef GDMLT_DECLARE_BSDF_MODEL

}  // namespace gdmlt::detail
