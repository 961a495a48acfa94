#!/usr/bin/env python3
"""Reference values of the Nishita single-scattering sky for tests/test_sky.cpp.

An independent transcription, in double-precision Python and without the project's code, of the
"Nishita (improved)" sky model of Blender's Cycles renderer (Blender 2.90, 2020): its constants
(Earth 6360 km, atmosphere 6420 km, Rayleigh scale height 8 km and 1.2361437e-5 /m at 550 nm
~ lambda^-4, Mie 2e-5 /m, scale height 1.2 km, extinction 1.11 x scattering, Cornette-Shanks phase
with g = 0.76, ozone tent 10-25-40 km with Cycles' ozone table), its 32 midpoint steps along the
view ray, its 8-point Gauss-Laguerre optical depth towards the sun (nodes / 25), its sun (a 5778 K
blackbody filling 6.79016e-5 sr) and its XYZ reduction (the CIE 1931 observer at 380, 400, ...,
780 nm, times 20 nm). Two choices of the project are followed rather than Cycles': the sun's
transmittance includes ozone, and the Earth's shadow is tested geometrically (Cycles tests only
whether the sun is below the viewer's horizon; the two agree for the directions printed here).

Run: python3 tests/sky_reference.py   (prints the rows pasted into tests/test_sky.cpp)
"""
import math

R_EARTH, R_ATM = 6360e3, 6420e3
OZONE = [3.25126849861e-9, 5.85395365047e-9, 1.977191155085e-8, 7.309568762914e-8, 2.0084561514287e-7,
         4.0383958096161e-7, 6.3551335912363e-7, 9.670704118097e-7, 1.5479740042441e-6, 2.0903864722333e-6,
         2.4612805616457e-6, 2.7355129946151e-6, 2.1512586312864e-6, 1.5905184079199e-6, 1.1235619797986e-6,
         7.3527551487574e-7, 4.6450130357806e-7, 3.3096079921048e-7, 2.2512612292678e-7, 1.487912926649e-7,
         1.6828623364192e-7]
# CIE 1931 2-degree observer at 380, 400, ..., 780 nm (CIE 015:2004 table)
CMF = [(0.001368, 0.000039, 0.006450), (0.014310, 0.000396, 0.067850), (0.134380, 0.004000, 0.645600),
       (0.348280, 0.023000, 1.747060), (0.290800, 0.060000, 1.669200), (0.095640, 0.139020, 0.812950),
       (0.004900, 0.323000, 0.272000), (0.063270, 0.710000, 0.078250), (0.290400, 0.954000, 0.020300),
       (0.594500, 0.995000, 0.003900), (0.916300, 0.870000, 0.001650), (1.062200, 0.631000, 0.000800),
       (0.854450, 0.381000, 0.000190), (0.447900, 0.175000, 0.000020), (0.164900, 0.061000, 0.000000),
       (0.046770, 0.017000, 0.000000), (0.011359, 0.004102, 0.000000), (0.002899, 0.001047, 0.000000),
       (0.000690, 0.000249, 0.000000), (0.000166, 0.000060, 0.000000), (0.000042, 0.000015, 0.000000)]
GL_X = [0.170279632305, 0.903701776799, 2.251086629866, 4.266700170288, 7.045905402393, 10.758516010181,
        15.740678641278, 22.863131736889]
GL_W = [0.437723410493, 1.033869347666, 1.669709765659, 2.376924701759, 3.208540913348, 4.268575510825,
        5.818083368672, 8.906226215292]
LAMBDA = [380 + 20 * i for i in range(21)]


def planck(lam_nm, T):
    h, c, k = 6.62607015e-34, 299792458.0, 1.380649e-23
    l = lam_nm * 1e-9
    return 2 * h * c * c / l ** 5 / math.expm1(h * c / (l * k * T)) * 1e-9


SUN = [planck(l, 5778.0) * 6.79016e-5 for l in LAMBDA]
RAY = [1.2361437e-5 * (550.0 / l) ** 4 for l in LAMBDA]


def dens(p):
    h = math.sqrt(sum(x * x for x in p)) - R_EARTH
    oz = h / 15e3 - 2 / 3 if 10e3 <= h < 25e3 else (8 / 3 - h / 15e3 if 25e3 <= h < 40e3 else 0.0)
    return (math.exp(-h / 8e3), math.exp(-h / 1.2e3), oz)


def to_top(p, d):
    b = sum(x * y for x, y in zip(p, d))
    c = sum(x * x for x in p) - R_ATM * R_ATM
    return -b + math.sqrt(max(b * b - c, 0.0))


def depth(p, d):
    L = to_top(p, d)
    out = [0.0, 0.0, 0.0]
    for x, w in zip(GL_X, GL_W):
        q = [p[i] + x / 25 * L * d[i] for i in range(3)]
        r = dens(q)
        for k in range(3):
            out[k] += r[k] * w / 25 * L
    return out


def shadowed(p, d):
    b = sum(x * y for x, y in zip(p, d))
    return b < 0 and sum(x * x for x in p) - b * b < R_EARTH * R_EARTH


def xyz(spec):
    return [sum(CMF[i][k] * spec[i] for i in range(21)) * 20 for k in range(3)]


def sky(view, sun, alt=0.0, air=1.0, dust=1.0, ozone=1.0):
    g = 0.76
    mu = sum(a * b for a, b in zip(view, sun))
    pr = 3 / (16 * math.pi) * (1 + mu * mu)
    pm = 3 * (1 - g * g) * (1 + mu * mu) / (8 * math.pi * (2 + g * g) * (1 + g * g - 2 * g * mu) ** 1.5)
    o = [0.0, 0.0, R_EARTH + alt]
    ds = to_top(o, view) / 32
    tv = [0.0, 0.0, 0.0]
    spec = [0.0] * 21
    sc = (air, dust, ozone)
    for s in range(32):
        p = [o[i] + (s + 0.5) * ds * view[i] for i in range(3)]
        r = [a * b for a, b in zip(dens(p), sc)]
        tv = [tv[k] + r[k] * ds for k in range(3)]
        if shadowed(p, sun):
            continue
        ts = [a * b for a, b in zip(depth(p, sun), sc)]
        t = [tv[k] + ts[k] for k in range(3)]
        for i in range(21):
            att = math.exp(-(t[0] * RAY[i] + t[1] * 1.11 * 2e-5 + t[2] * OZONE[i]))
            spec[i] += att * (r[0] * RAY[i] * pr + r[1] * 2e-5 * pm) * SUN[i] * ds
    return xyz(spec)


def sun_irradiance(elev, alt=0.0, air=1.0, dust=1.0, ozone=1.0):
    e = max(elev, 0.0)
    t = depth([0.0, 0.0, R_EARTH + alt], [math.cos(e), 0.0, math.sin(e)])
    return xyz([SUN[i] * math.exp(-(t[0] * air * RAY[i] + t[1] * dust * 1.11 * 2e-5 + t[2] * ozone * OZONE[i]))
                for i in range(21)])


def direction(elev_deg, azim_deg):
    e, a = math.radians(elev_deg), math.radians(azim_deg)
    return [math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)]


if __name__ == "__main__":
    # sun elevation, view elevation, view azimuth from the sun (degrees), altitude, air, dust, ozone
    cases = [(30, 90, 0, 0, 1, 1, 1), (30, 10, 0, 0, 1, 1, 1), (30, 40, 150, 0, 1, 1, 1),
             (5, 20, 30, 0, 1, 1, 1), (5, 60, 180, 1000, 2, 0.5, 1), (-3, 15, 0, 0, 1, 1, 3)]
    for se, ve, va, alt, air, dust, oz in cases:
        v = sky(direction(ve, va), direction(se, 0), alt, air, dust, oz)
        print("{%g, %g, %g, %g, %g, %g, %g, {%.7g, %.7g, %.7g}}," % (se, ve, va, alt, air, dust, oz, *v))
    for se in (60, 10, 2):
        print("sun %g: {%.7g, %.7g, %.7g}," % (se, *sun_irradiance(math.radians(se))))
