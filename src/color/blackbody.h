// blackbody.h: the colour of thermal emission: Planck's law against the CIE 1931 observer.
//
// Design: a blackbody's spectral radiance B(lambda, T) (Planck's law, CODATA 2018 constants) is
// integrated against the CIE 1931 2-degree colour-matching functions (data/cie/, embedded by
// cmake/embed_cie.cmake) on their own 1 nm grid, 360-830 nm, with pbrt-v4's convention
// Y = sum(S y-bar) / sum(y-bar), so a flat spectrum of 1 has Y = 1 and a pbrt scene's Lescale
// means the same here. XYZ goes to linear sRGB (Rec.709 primaries, D65 white) by a matrix derived
// from the primaries' chromaticities. Below about 1900 K the blackbody lies outside the sRGB gamut
// (its blue, and below ~950 K its green, are negative); RGB mode sets those components to 0, the
// only departure from the spectral integral (docs/scene-format.md "Blackbody emission").
// The kernels read a table of these colours (make_blackbody_table) spaced evenly in a warped
// temperature that is smooth in both of Planck's regimes, and interpolate it linearly.
#pragma once
#include <array>
#include <string>
#include <vector>

namespace spectrack {

struct CieSample {
  int lambda_nm;
  double x, y, z;
};
constexpr int kCieSamples = 471;  // 360..830 nm, 1 nm apart
extern const CieSample kCie1931[kCieSamples];

// How a blackbody spectrum is scaled before its colour is taken (emission.normalization):
//   peak:      B(lambda, T) / B(lambda_max, T), the spectrum's maximum is 1 (pbrt-v4's BlackbodySpectrum);
//   luminance: scaled to Y = 1 (colour only: temperature sets the hue, `scale` the brightness);
//   none:      B itself in W sr^-1 m^-2 nm^-1 (brightness grows as ~T^4: physical fire).
enum class BlackbodyNorm { Peak, Luminance, None };
// Their names in scene files (emission.normalization) and messages, one table for both ways.
const char* blackbody_norm_name(BlackbodyNorm n);
bool blackbody_norm_from_name(const std::string& name, BlackbodyNorm* n);  // false: no such name
std::string blackbody_norm_names();                                         // "peak, luminance, none"

using Rgb = std::array<double, 3>;

// The hottest temperature a scene may ask for (K): far above any flame (the Sun's core is 1.6e7 K)
// and well inside double precision for Planck's law at the peak wavelength.
constexpr double kMaxTemperature = 1e9;

double cie_y_integral();                       // sum of y-bar over the table (1 nm steps): 106.857
double planck(double lambda_nm, double T);     // W sr^-1 m^-2 nm^-1; 0 for T <= 0
double log_planck(double lambda_nm, double T); // its log, finite for T > 0 (no underflow)
double planck_peak_nm(double T);               // Wien's displacement law: lambda_max = b / T
// CIE XYZ of the normalised spectrum S = B / N(T), Y = sum(S y-bar) / sum(y-bar); *log_norm (when
// given) receives ln N(T): peak, ln B(lambda_max, T); luminance, ln (sum(B y-bar) / sum(y-bar));
// none, 0. Spectral mode evaluates S(lambda) = exp(ln B(lambda, T) - ln N(T)) per wavelength.
Rgb blackbody_xyz(double T, BlackbodyNorm norm, double* log_norm = nullptr);
// The largest value of S = B / N(T) over 360..830 nm (B is unimodal in lambda: at the peak
// wavelength clamped into that range).
double blackbody_spectrum_max(double T, BlackbodyNorm norm);
Rgb xyz_to_linear_srgb(const Rgb& xyz);
Rgb linear_srgb_to_xyz(const Rgb& rgb);
// blackbody_xyz in linear sRGB with negative components set to 0 (outside the gamut).
Rgb blackbody_linear_srgb(double T, BlackbodyNorm norm);

// The kernels' table (kernels/medium.h blackbody_rgb): entries (r, g, b, ln N) evenly spaced in the
// warped temperature w(T) = A / T - B ln T (decreasing in T), entry i at
// w = warp_first + i / entries_per_warp: entry 0 is T_hi, the last max(T_lo, kBlackbodyTableFloor).
// Wien's regime (T << A) changes as exp(-c2 / (lambda T)), smooth in 1/T (the A / T term, A = c2 /
// 400 nm); the Rayleigh-Jeans regime (hot) as powers of T, smooth in ln T (B = 4: the peak
// normalisation's T^-4); with 16384 entries linear interpolation in w stays within ~1e-4 of the
// integral from 100 K to 1e9 K. Below the floor, 100 K, the colour is that of 100 K to float
// precision (0 for peak and none; the red end of the spectrum for luminance). ln N (blackbody_xyz)
// serves spectral mode, which evaluates Planck's law itself at a path's wavelengths and divides by
// the normaliser, interpolated in the table as the colours are (it is smooth in w too).
constexpr double kBlackbodyWarpA = 36000.0;  // K
constexpr double kBlackbodyWarpB = 4.0;
constexpr double kBlackbodyTableFloor = 100.0;  // K
double blackbody_warp(double T);
struct BlackbodyTable {
  double warp_first = 0;
  double entries_per_warp = 0;
  int entries = 0;
  std::vector<float> rgbn;  // 4 floats per entry: linear sRGB, ln N
  double max_value = 0;     // the largest r, g or b
  double spectrum_max = 0;  // the largest blackbody_spectrum_max over the entries
};
BlackbodyTable make_blackbody_table(double T_lo, double T_hi, BlackbodyNorm norm, int entries);

}  // namespace spectrack
