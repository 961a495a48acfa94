/* spectrum.h: spectral mode's device functions (docs/spectral.md): the wavelengths of a path, an RGB
 * colour's smooth spectrum at them, and the film's linear sRGB from them. The device twin of
 * src/color/spectrum.h (read it first); tests/test_spectrum.cpp holds the two to each other.
 *
 * Wavelengths: pbrt-v4's scheme, a hero from u and the others from u + k / n (wrapped),
 * each through the visible-wavelength density p(lambda) = 0.0039398042 / cosh^2(0.0072 (lambda -
 * 538)) on [360, 830] nm, inverted in closed form. Spectra: the Jakob-Hanika sigmoid polynomial
 * in a float4 (c0, c1, c2, scale), s(lambda) = scale S(c0 u^2 + c1 u + c2), u = (lambda - 360) / 470;
 * rgb2spec_lookup reads the build-time table (z levels, then 9 res^3 coefficients, as
 * serialize_rgb2spec_table lays them out after its header) exactly as the host's rgb2spec does.
 * Film: linear sRGB = (1/n) sum_i L_i F(lambda_i) / p(lambda_i), with F the white-balanced
 * observer weights on the 1 nm grid (film_rgb_weights), interpolated linearly from a table the
 * host generates into the program. The renderer's spectral mode carries n = 4 wavelengths, one
 * per lane (the lanes that hold the three colour channels in rgb mode: masks, per-channel
 * tracking, spectral MIS); the probe tests them against the host. */
#ifndef SPECTRACK_SPECTRUM_H
#define SPECTRACK_SPECTRUM_H

#include "types.h"
#include "features.h"
#include "film_table.h"

#define ST_LAMBDA_MIN 360.0f
#define ST_LAMBDA_MAX 830.0f
#define ST_FILM_SAMPLES 471 /* F on the observer's 1 nm grid, 360..830 nm (kCieSamples) */

inline float visible_wavelength_pdf(float lambda) {
  if (!(lambda >= ST_LAMBDA_MIN && lambda <= ST_LAMBDA_MAX)) return 0.0f;
  float c = cosh(0.0072f * (lambda - 538.0f));
  return 0.0039398042f / (c * c);
}

inline float sample_visible_wavelength(float u) {
  return clamp(538.0f - 138.888889f * atanh(0.85691062f - 1.82750197f * u), ST_LAMBDA_MIN, ST_LAMBDA_MAX);
}

/* The n wavelengths (n = 3 or 4) of a path from one uniform: a hero from u and the others from
 * u + k / n (wrapped), in lanes 0 .. n - 1; a lane >= n is 0 (no wavelength, density 0). */
inline float4 sample_wavelengths(float u, int n) {
  const float step = 1.0f / (float)n;
  float4 ui = (float4)(u) + (float4)(0.0f, step, 2.0f * step, 3.0f * step);
  ui = select(ui, ui - 1.0f, isgreaterequal(ui, (float4)(1.0f)));
  return (float4)(sample_visible_wavelength(ui.x), sample_visible_wavelength(ui.y), sample_visible_wavelength(ui.z),
                  n > 3 ? sample_visible_wavelength(ui.w) : 0.0f);
}

/* Each lane's density (0 for an unused lane, whose wavelength 0 lies outside the range). */
inline float4 wavelength_pdfs(float4 lambda) {
  return (float4)(visible_wavelength_pdf(lambda.x), visible_wavelength_pdf(lambda.y), visible_wavelength_pdf(lambda.z),
                  visible_wavelength_pdf(lambda.w));
}

/* s(lambda) per lane; S is 0 or 1 where x^2 overflows. */
inline float4 rgb2spec_eval(float4 coeffs, float4 lambda) {
  float4 u = (lambda - ST_LAMBDA_MIN) * (1.0f / (ST_LAMBDA_MAX - ST_LAMBDA_MIN));
  /* not mad: its rounding is the device's choice */
  float4 x = ((float4)(coeffs.x) * u + (float4)(coeffs.y)) * u + (float4)(coeffs.z);
  float4 x2 = x * x;
  float4 r = sqrt(1.0f + x2);
  /* 1/2 + x / (2 r) without cancellation for x << 0, as the host's sigmoid */
  float4 s = select(1.0f - 0.5f / (r * (r + x)), 0.5f / (r * (r - x)), isless(x, (float4)(0.0f)));
  s = select(s, select((float4)(0.0f), (float4)(1.0f), isgreater(x, (float4)(0.0f))), isinf(x2));
  return coeffs.w * s;
}

/* The coefficients (c0, c1, c2, scale) of a colour in [0, 1]^3 (clamped; NaN reads as 0). */
inline float4 rgb2spec_lookup(__global const float* table, int res, float3 rgb) {
  rgb = fmin(fmax(rgb, (float3)(0.0f)), (float3)(1.0f));
  if (rgb.x == rgb.y && rgb.y == rgb.z) return (float4)(0.0f, 0.0f, 0.0f, 2.0f * rgb.x); /* flat */
  int l = rgb.x >= rgb.y ? (rgb.x >= rgb.z ? 0 : 2) : (rgb.y >= rgb.z ? 1 : 2);
  float z = l == 0 ? rgb.x : (l == 1 ? rgb.y : rgb.z);
  float a = l == 0 ? rgb.y : (l == 1 ? rgb.z : rgb.x); /* component l + 1 */
  float b = l == 0 ? rgb.z : (l == 1 ? rgb.x : rgb.y); /* component l + 2 */
  float x = a / z, y = b / z;
  __global const float* zs = table;
  float scale = 1.0f;
  if (z < zs[1]) { /* darker than the first level: that level's spectrum, scaled */
    scale = z / zs[1];
    z = zs[1];
  }
  int lo = 1, hi = res - 2; /* the last level <= z, within [1, res - 2] */
  while (lo < hi) {
    int mid = (lo + hi + 1) / 2;
    if (zs[mid] <= z) lo = mid;
    else hi = mid - 1;
  }
  int zi = lo;
  float tz = clamp((z - zs[zi]) / (zs[zi + 1] - zs[zi]), 0.0f, 1.0f);
  float xf = x * (float)(res - 1), yf = y * (float)(res - 1);
  int xi = min((int)xf, res - 2), yi = min((int)yf, res - 2);
  float tx = xf - (float)xi, ty = yf - (float)yi;
  __global const float* co = table + res;
  float3 c = (float3)(0.0f);
  for (int dz = 0; dz < 2; ++dz)
    for (int dy = 0; dy < 2; ++dy)
      for (int dx = 0; dx < 2; ++dx) {
        float w = (dz ? tz : 1.0f - tz) * (dy ? ty : 1.0f - ty) * (dx ? tx : 1.0f - tx);
        size_t i = ((((size_t)l * res + zi + dz) * res + yi + dy) * res + xi + dx) * 3;
        c += w * (float3)(co[i], co[i + 1], co[i + 2]);
      }
  return (float4)(c, scale);
}

/* A spectrum's values at a path's four wavelengths. */
inline float4 spectrum_at(float4 coeffs, float4 lambda) { return rgb2spec_eval(coeffs, lambda); }

inline int spectral_mode(__constant const st_scene* scene) {
  return ST_HAS_SPECTRAL && scene->color == ST_FILM_COLOR_SPECTRAL;
}

/* The lanes a path of the scene can carry: the three colour channels in rgb mode (w unused), the
 * four wavelengths in spectral mode. */
inline float4 scene_lanes(__constant const st_scene* scene) {
  return (float4)(1.0f, 1.0f, 1.0f, spectral_mode(scene) ? 1.0f : 0.0f);
}
inline int scene_n_lanes(__constant const st_scene* scene) { return spectral_mode(scene) ? 4 : 3; }

/* B(lambda, T) / N per lane, ln N = log_norm: Planck's law in W sr^-1 m^-2 nm^-1
 * (src/color/blackbody.cpp log_planck, CODATA 2018: ln(2 h c^2) in these units and c2 = h c / k in
 * nm K) over a normaliser, as exp(ln(2 h c^2) - ln N - x) / (lambda^5 (1 - exp(-x))), x =
 * c2 / (lambda T): one exp and one expm1 per lane, finite where B / N is (the exponent holds the
 * cold regime's e^-x and the normaliser, which apart overflow a float); 0 in an unused lane
 * (lambda 0). */
inline float4 blackbody_over_norm(float4 lambda, float T, float log_norm) {
  const float4 x = 14387768.8f / (lambda * T);
  const float4 l2 = lambda * lambda;
  const float4 v = exp((float4)(46.2265312f - log_norm) - x) / (l2 * l2 * lambda * -expm1(-x));
  return select(v, (float4)(0.0f), islessequal(lambda, (float4)(0.0f)));
}

/* st_film_table (generated into every program by the host, src/device/kernel_source.cpp film_table_source):
 * entry i is the wavelength 360 + i nm: xyz = the film's weights F (film_rgb_weights), w = CIE D65
 * (cie_d65), both linear between the entries as on the host; 0 outside 360..830 nm. */
inline float4 film_table_at(float lambda) {
  if (!(lambda >= ST_LAMBDA_MIN && lambda <= ST_LAMBDA_MAX)) return (float4)(0.0f);
  float f = lambda - ST_LAMBDA_MIN;
  int i = min((int)f, ST_FILM_SAMPLES - 2);
  return mix(st_film_table[i], st_film_table[i + 1], f - (float)i);
}

/* An upsampled light colour at the path's wavelengths: its spectrum times D65, so that the film
 * gives the colour back (the fit is made under D65, src/color/spectrum.h). */
inline float4 d65_at(float4 lambda) {
  return (float4)(film_table_at(lambda.x).w, film_table_at(lambda.y).w, film_table_at(lambda.z).w,
                  film_table_at(lambda.w).w);
}
inline float4 illuminant_at(float4 coeffs, float4 lambda) { return spectrum_at(coeffs, lambda) * d65_at(lambda); }

/* One sample's linear sRGB (w = 0) from the radiance L at its n wavelengths: (1/n) sum_i
 * L_i F(lambda_i) / p(lambda_i), unused lanes (pdf 0) adding nothing. A per-channel tracker's path
 * carries one lane (the others 0), so the sum over a sample's paths is the sample's estimate. */
inline float4 film_rgb(float4 L, float4 lambda, float4 pdf, int n) {
  float4 w = select(L / pdf, (float4)(0.0f), isequal(pdf, (float4)(0.0f))) * (1.0f / (float)n);
  float4 rgb = w.x * film_table_at(lambda.x) + w.y * film_table_at(lambda.y) + w.z * film_table_at(lambda.z) +
               w.w * film_table_at(lambda.w);
  return (float4)(rgb.xyz, 0.0f);
}

#endif
