// spectral_pack.h: turns a packed rgb scene into spectral mode's (render.color "spectral",
// --spectral; docs/spectral.md).
//
// Design: the scene is packed in rgb first (scene_pack.cpp), so every check and derived quantity
// (float limits, the majorant hierarchy's cost model, light powers, the feature mask) is made once,
// on the colours the user wrote. This pass then replaces the colours the kernels read with smooth
// spectra: each medium's sigma_a and sigma_s (per unit density) and emitted radiance, and each
// light's radiance, become the sigmoid-polynomial coefficients of src/color/spectrum.h, upsampled
// by the fitter (exact to 1e-7 in linear sRGB; rgb2spec_unbounded) once per colour. Radiances are
// illuminants: the kernels multiply their spectrum by CIE D65 (kernels/spectrum.h illuminant_at),
// so a light of colour c gives the film c back. The majorants need nothing from here: the kernels
// take each medium's extinction at a path's own wavelengths (kernels/walker.h st_walker), the
// exact bound over the wavelengths it carries; the extinction's largest value over all visible
// wavelengths (spectrum_max, in closed form) is checked to stay a float.
// Blackbody emission needs no upsampling: the kernels evaluate Planck's law at a path's
// wavelengths (kernels/medium.h blackbody_spectral_Le), divided by the normaliser the rgb table
// also uses and scaled into the film's unit (film_emission_scale), so both modes render one
// colour; only its out-of-gamut components (below ~1900 K), which rgb mode sets to 0, stay
// negative here, as the film's linear sRGB of the spectrum. This pass gives such a medium its
// scale and, for a constant temperature, its normaliser; the packer checked its bounds.
// Environment maps keep their scale; each texel's colour becomes its coefficients from the
// table (rgb2spec_unbounded_lookup, within the table's 7e-4: a map has too many texels to fit one
// by one), in place, and the sampling distribution stays the one built on the rgb texels.
// Colour grids stay rgb: the kernels turn each collision's colour into a spectrum through the
// build-time table, which this pass puts in the grid buffer once (kernels/medium.h).
// Film layers other than variance are refused (integrator/settings.cpp).
#pragma once
#include <string>

#include "scene/scene_pack.h"
#include "scene/scene.h"

namespace spectrack {

// In place: the media and lights of `packed` (packed from `scene`) in spectral mode. Throws Error
// naming the scene file and field of a feature spectral mode does not support yet.
void make_spectral(const SceneDesc& scene, PackedScene& packed);

// The largest value over 360..830 nm of the spectrum with coefficients (c0, c1, c2, scale)
// (kernels/spectrum.h rgb2spec_eval), exactly: the sigmoid is increasing, so its largest value is
// at the quadratic's largest value on u in [0, 1].
double spectrum_max(const st_float4& coeffs);

}  // namespace spectrack
