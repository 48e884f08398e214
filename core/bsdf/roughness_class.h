// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// How a BSDF lobe scatters, as shifts and the manifold walk need to know it. The threshold that
// separates glossy from delta-like roughness is defined here and nowhere else.

namespace gdmlt {

enum class RoughnessClass {
    Diffuse,  // broad lobe: a vertex that can be reconnected to
    Glossy,   // rough but peaked: half-vector copy rather than reconnection
    Delta,    // a Dirac lobe (smooth mirror / glass): only specular chains pass it
};

/// Microfacet alpha below which a lobe is treated as delta-like by shifts (not by sampling:
/// sampling and evaluation always use the true alpha). Lehtinen et al. 2013 and Kettunen et
/// al. 2015 classify vertices by roughness in the same way; 0.001 matches the smallest alpha
/// the chi-square tests cover.
inline constexpr float kDeltaLikeAlpha = 1e-3f;
/// Alpha above which a glossy lobe is broad enough to reconnect to.
inline constexpr float kDiffuseLikeAlpha = 0.3f;

inline RoughnessClass classify_alpha(float alpha) {
    if (alpha < kDeltaLikeAlpha) return RoughnessClass::Delta;
    if (alpha < kDiffuseLikeAlpha) return RoughnessClass::Glossy;
    return RoughnessClass::Diffuse;
}

const char* to_string(RoughnessClass c);

}  // namespace gdmlt
