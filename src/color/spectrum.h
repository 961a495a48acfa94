// spectrum.h: smooth spectra from RGB colours (Jakob and Hanika 2019) and the CIE illuminant D65,
// the colour side of spectral mode (docs/spectral.md).
//
// Design: a colour c in [0, 1]^3 (linear sRGB, a reflectance or an albedo) becomes the spectrum
//   s(lambda) = scale * S(c0 u^2 + c1 u + c2),   u = (lambda - 360 nm) / 470 nm,
//   S(x) = 1/2 + x / (2 sqrt(1 + x^2)),
// the sigmoid-polynomial model of Jakob and Hanika, "A Low-Dimensional Function Space for
// Efficient Spectral Upsampling" (Eurographics 2019): smooth, within [0, scale] at every
// wavelength (with scale <= 1 an upsampled reflectance never gains energy), three coefficients
// per colour. The coefficients of a colour are those whose spectrum, lit by CIE D65 and seen by
// the CIE 1931 2-degree observer (sums over the observer's 1 nm grid, 360-830 nm), has that
// colour's linear sRGB; Rgb2SpecFit finds them by Levenberg-Marquardt to 1e-7. The residual is
// taken in linear sRGB, the quantity the renderer's film accumulates (the paper's CIELAB residual
// weighs dark colours more; an RGB residual bounds the round-trip error the tests check).
//
// A table of coefficients over the RGB cube is generated at build time by
// tools/rgb2spec_table.cpp with this file's fitter (make_rgb2spec_table) and embedded in the
// library (rgb2spec_srgb). As in the paper, there are three tables, one per largest component
// l; each is indexed by that component z = c[l] on a grid dense near 0 and 1 (smoothstep of
// smoothstep) and by the other two divided by it, c[l+1] / z and c[l+2] / z, on a uniform grid.
// The fit walks each (l, x, y) column in z from a dark level, every level starting from its
// neighbour's coefficients (the first from the gray of the same z, by continuation), so
// neighbouring entries lie on one branch of solutions and interpolate sensibly. Lookups
// (rgb2spec) interpolate the coefficients trilinearly, as a kernel would: at res 64 the colour
// comes back within 2e-4 on average, at most 7e-4 for largest component < 0.5, 1.9e-3 below 0.97
// and 5.5e-3 above, where the spectra saturate towards 1 and the coefficients grow fast
// (bench/rgb2spec_accuracy, bench/RESULTS.md "RGB upsampling"). Scene constants are upsampled
// once on the host (rgb2spec_fitted): the table's coefficients refined by the fitter, exact to
// 1e-7. Gray colours (r = g = b) bypass the table exactly: flat, c = 0 and scale = 2 r. Colours
// darker than the first nonzero z level (1.7e-6) read that level, scaled down (exact in
// brightness: RGB is linear in the spectrum); the fit's absolute 1e-7 leaves their hue
// approximate, which at that brightness nothing can see.
// Unbounded colours (scattering coefficients, radiances) are upsampled as pbrt-v4's
// RGBUnboundedSpectrum: divided by twice their largest component, then scaled back
// (rgb2spec_unbounded).
//
// White balance: the sRGB matrix comes from D65's standard chromaticity (0.3127, 0.3290), the
// tabulated D65 through the 1 nm observer is 2e-5 away; the fitter scales each channel so that a
// flat spectrum of 1 is exactly (1, 1, 1) (spectrum.cpp). A spectral film must use the same
// weights for white to stay white.
#pragma once
#include <array>
#include <cstddef>
#include <string>
#include <vector>

#include "color/blackbody.h"

namespace spectrack {

// CIE standard illuminant D65 (data/cie/cie_d65_5nm.csv, embedded by cmake/embed_cie.cmake):
// relative spectral power, 300-830 nm in 5 nm steps, S(560 nm) = 100.
struct IlluminantSample {
  int lambda_nm;
  double s;
};
constexpr int kCieD65Samples = 107;
extern const IlluminantSample kCieD65[kCieD65Samples];
double cie_d65(double lambda_nm);  // linear between the table's samples, 0 outside 300-830 nm

constexpr double kSpectrumLambdaMin = 360.0;  // nm: the observer table's range, the model's u = 0..1
constexpr double kSpectrumLambdaMax = 830.0;

double sigmoid(double x);  // S(x) above, in a form without cancellation; 0 and 1 at -inf and +inf

// s(lambda) = scale * S(c0 u^2 + c1 u + c2)
struct RgbSpectrum {
  std::array<double, 3> c{};
  double scale = 1;
  double operator()(double lambda_nm) const;
};

// The film of spectral mode: linear sRGB = integral of L(lambda) F(lambda) d lambda, with
// F = M (x-bar, y-bar, z-bar) / sum(y-bar D65), white-balanced so that D65 itself is (1, 1, 1)
// (see White balance above). film_rgb_weights holds F on the observer's 1 nm grid (360..830 nm,
// kCieSamples entries); film_rgb_weight interpolates it linearly (0 outside).
const std::vector<Rgb>& film_rgb_weights();
Rgb film_rgb_weight(double lambda_nm);
// An emitted spectrum S in blackbody.h's convention (Y = sum(S y-bar) / sum(y-bar): a flat
// spectrum of 1 has Y = 1) reaches this film as S times sum(y-bar D65) / sum(y-bar) (98.89): the
// film's unit is D65's luminance. Spectral mode's blackbody emission carries the factor, so that
// both modes render one colour (kernels/medium.h blackbody_spectral_Le).
double film_emission_scale();

// Four wavelengths per path (pbrt-v4's scheme): a hero wavelength from u, three more from
// u + 1/4, u + 1/2, u + 3/4 (wrapped), each through the visible-wavelength importance density
// p(lambda) = 0.0039398042 / cosh^2(0.0072 (lambda - 538 nm)) on [360, 830] nm; an estimate
// of the film is (1/4) sum_i L(lambda_i) F(lambda_i) / p(lambda_i).
double visible_wavelength_pdf(double lambda_nm);
double sample_visible_wavelength(double u);
std::array<double, 4> sample_wavelengths(double u);

// Finds the coefficients of colours; the weights W(lambda) = F(lambda) D65(lambda) on the 1 nm
// grid are computed once per fitter.
class Rgb2SpecFit {
 public:
  Rgb2SpecFit();
  // the linear sRGB of s lit by D65: sum over the observer's 1 nm grid of s(lambda) W(lambda)
  Rgb rgb_of(const RgbSpectrum& s) const;
  // Levenberg-Marquardt from c towards the colour target (in [0, 1]^3); c holds the result. Returns
  // the largest |rgb_of(c) - target| component reached: <= tolerance when it converged.
  double fit(const Rgb& target, std::array<double, 3>& c, double tolerance = 1e-7, int max_iterations = 200) const;

 private:
  std::vector<double> u_;                  // (lambda - 360) / 470 per sample
  std::vector<std::array<double, 3>> w_;   // W(lambda) per sample
};

struct Rgb2SpecTable {
  int res = 0;                 // levels per axis
  std::vector<float> z;        // res levels of the largest component, z[0] = 0, z[res - 1] = 1
  std::vector<float> coeffs;   // [l][zi][yi][xi][3], l = the largest component's index
  double max_residual = 0;     // the fit's worst |rgb - target| over the grid (the generator's report)
};

// The table for a grid of res levels, fitted on `threads` threads (tools/rgb2spec_table.cpp).
// Throws std::runtime_error naming the colour if a fit does not converge.
Rgb2SpecTable make_rgb2spec_table(int res, int threads);
// The table's file format (the build writes it, the library embeds it): "spectrack-rgb2spec 1\n",
// then int32 res, float32 max_residual, res float32 z levels, 9 res^3 float32 coefficients, little endian.
std::vector<char> serialize_rgb2spec_table(const Rgb2SpecTable& t);
// Parses `bytes`; on a damaged table returns false and says why in *error.
bool parse_rgb2spec_table(const void* bytes, std::size_t size, Rgb2SpecTable& t, std::string* error);

// The spectrum of a colour in [0, 1]^3 (components outside are clamped) from the table alone,
// as a kernel would look it up: within 2e-3 of the colour below a largest component of 0.97,
// 5.5e-3 above (bench/RESULTS.md "RGB upsampling" has the measured figures).
RgbSpectrum rgb2spec(const Rgb2SpecTable& t, const Rgb& rgb);
// The same refined by the fitter from the table's coefficients: exact to the fit's 1e-7 (scene
// constants are upsampled this way, once per colour on the host).
RgbSpectrum rgb2spec_fitted(const Rgb2SpecFit& f, const Rgb2SpecTable& t, const Rgb& rgb);
// The spectrum of a colour with components >= 0 of any size (a scattering coefficient, a
// radiance): scale 2 max(rgb) times the fitted spectrum of rgb / (2 max(rgb)), whose largest
// component is 1/2 (pbrt-v4's RGBUnboundedSpectrum). Throws std::domain_error on a non-finite
// component (callers validate scene values first).
RgbSpectrum rgb2spec_unbounded(const Rgb2SpecFit& f, const Rgb2SpecTable& t, const Rgb& rgb);
// The same from the table alone, without the fitter's refinement (for colours too many to fit one
// by one: environment map texels): the colour comes back within the table's accuracy for a
// largest component of 1/2 (7e-4 of it). Its scale is exactly 2 max(rgb) (0 for black), the
// largest component a kernel can read back from it. Throws std::domain_error as above.
RgbSpectrum rgb2spec_unbounded_lookup(const Rgb2SpecTable& t, const Rgb& rgb);

// The table generated at build time for linear sRGB under D65 (tools/rgb2spec_table.cpp), parsed
// once from the library's embedded copy.
const Rgb2SpecTable& rgb2spec_srgb();

}  // namespace spectrack
