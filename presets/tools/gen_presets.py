#!/usr/bin/env python3
"""Generate the physically motivated modal presets in presets/ and check them.

Usage:  python3 presets/tools/gen_presets.py          (writes ../*.toml, then checks them)
        python3 presets/tools/gen_presets.py --check  (only parses and checks the existing files)

Pure Python 3.11+ (math + tomllib), no numpy. Every number in the scene files is computed here,
and each file carries a comment block saying where the numbers come from.

Conventions (shared/DESIGN.md section 2): unit modal mass, weights w_{p,i} are mass-normalised mode
shape values [1/sqrt(kg)], displacement at p = sum_i w_{p,i} x_i, a single mode of weight w looks
like a mass 1/w^2 at that point, modal damping term 2 ln(1000)/T60 (T60 = 60 dB amplitude decay
time, amplitude envelope exp(-alpha t) with alpha = ln(1000)/T60).

Contact design rule used by every preset (a linear spring-damper against one mode):
  M1    = 1/w_{c,1}^2                 apparent mass of the lowest mode at the contact point
  m_eff = m_h M1 / (m_h + M1)         reduced mass of hammer and that mode
  omega_d = pi / t_c,  omega_0 = omega_d / sqrt(1 - zeta^2)
  k = m_eff omega_0^2,  c = 2 zeta sqrt(k m_eff)
so that a half period of the damped contact oscillator lasts t_c. The check below also simulates the
full multi-mode impact (RK4 in contact, exact damped-oscillator steps in flight) and prints the real
contact time, the number of contacts and the pickup peak, which sets each pickup gain (peak ~ 0.5).
"""

import math
import os
import sys
import tomllib

HERE = os.path.dirname(os.path.abspath(__file__))
OUT_DIR = os.path.dirname(HERE)  # presets/
LN1000 = math.log(1000.0)
RHO_AIR = 1.204  # kg/m^3, 20 C
C_AIR = 343.0  # m/s, 20 C
FS = 44100.0
TARGET_PEAK = 0.5  # pickup gain is chosen so the simulated pickup peak is about this


# ----------------------------------------------------------------------------------------------
# small numeric helpers
# ----------------------------------------------------------------------------------------------

def bisect(f, a, b, tol=1e-13):
    fa = f(a)
    for _ in range(200):
        m = 0.5 * (a + b)
        fm = f(m)
        if (fm > 0) == (fa > 0):
            a, fa = m, fm
        else:
            b = m
        if b - a < tol:
            break
    return 0.5 * (a + b)


def beam_roots(n):
    """First n roots lambda of cos(l) cosh(l) = 1 (free-free and clamped-clamped beams)."""
    roots = []
    for k in range(1, n + 1):
        guess = (k + 0.5) * math.pi
        f = lambda l: math.cos(l) * math.cosh(l) - 1.0
        # scale to keep the function O(1): cos(l) - 1/cosh(l)
        g = lambda l: math.cos(l) - 1.0 / math.cosh(l)
        roots.append(bisect(g, guess - 0.3, guess + 0.3))
        assert abs(f(roots[-1])) < 1e-6 * math.cosh(roots[-1])
    return roots


def simpson(f, n=4000):
    h = 1.0 / n
    s = f(0.0) + f(1.0)
    for i in range(1, n):
        s += (4 if i % 2 else 2) * f(i * h)
    return s * h / 3.0


class BeamMode:
    """Euler-Bernoulli beam mode on xi = x/L in [0, 1], normalised to mean square 1 over the length.

    bc = "free" (free-free) or "clamped" (clamped-clamped). psi(xi) and psi''(xi) (d2/dxi2)."""

    def __init__(self, lam, bc):
        self.lam, self.bc = lam, bc
        self.sigma = (math.cosh(lam) - math.cos(lam)) / (math.sinh(lam) - math.sin(lam))
        self.scale = 1.0
        ms = simpson(lambda xi: self.psi(xi) ** 2)
        self.scale = 1.0 / math.sqrt(ms)

    def psi(self, xi):
        l, s = self.lam * xi, self.sigma
        if self.bc == "free":
            v = math.cosh(l) + math.cos(l) - s * (math.sinh(l) + math.sin(l))
        else:
            v = math.cosh(l) - math.cos(l) - s * (math.sinh(l) - math.sin(l))
        return self.scale * v

    def psi2(self, xi):
        l, s = self.lam * xi, self.sigma
        if self.bc == "free":
            v = math.cosh(l) - math.cos(l) - s * (math.sinh(l) - math.sin(l))
        else:
            v = math.cosh(l) + math.cos(l) - s * (math.sinh(l) + math.sin(l))
        return self.scale * self.lam ** 2 * v


def torsion_beta(aspect):
    """Saint-Venant torsion constant factor beta in K_t = beta b h^3 for a b x h rectangle (b >= h).
    Series solution (Timoshenko & Goodier): beta = 1/3 (1 - 192/pi^5 (h/b) sum_odd tanh(n pi b/2h)/n^5)."""
    r = 1.0 / aspect
    s = sum(math.tanh(n * math.pi * aspect / 2.0) / n ** 5 for n in range(1, 200, 2))
    return (1.0 - 192.0 / math.pi ** 5 * r * s) / 3.0


def timoshenko_factor(k, h, E, G, kappa=5.0 / 6.0):
    """First-order shear + rotary-inertia correction of an Euler-Bernoulli bending frequency
    (Timoshenko beam, small (k r)^2): f_T / f_EB ~ 1 - 0.5 (k r)^2 (1 + E/(kappa G)), r = h/sqrt(12),
    k = bending wavenumber lambda_n / L."""
    r = h / math.sqrt(12.0)
    return 1.0 - 0.5 * (k * r) ** 2 * (1.0 + E / (kappa * G))


def hertz_contact_time(m, R, E_star, v):
    """Hertz impact duration of a sphere (radius R) of mass m on a flat at speed v:
    t = 2.868 (m^2 / (R E*^2 v))^(1/5)  (Johnson, Contact Mechanics, sec. 11.4)."""
    return 2.868 * (m * m / (R * E_star ** 2 * v)) ** 0.2


def e_star(E1, nu1, E2, nu2):
    return 1.0 / ((1 - nu1 ** 2) / E1 + (1 - nu2 ** 2) / E2)


def t60_from_alpha(alpha):
    return LN1000 / alpha


def design_contact(m_h, w_c1, t_c, zeta):
    M1 = 1.0 / w_c1 ** 2
    m_eff = m_h * M1 / (m_h + M1)
    omega_d = math.pi / t_c
    omega_0 = omega_d / math.sqrt(1.0 - zeta ** 2)
    k = m_eff * omega_0 ** 2
    c = 2.0 * zeta * math.sqrt(k * m_eff)
    return dict(M1=M1, m_eff=m_eff, omega_d=omega_d, omega_0=omega_0, k=k, c=c, t_c=t_c, zeta=zeta)


def contact_comment(d, m_h):
    return [
        "Contact (linear spring-damper, DESIGN.md eq. 9), designed against the lowest mode:",
        f"  M1 = 1/w_c1^2 = {d['M1']:.5g} kg, hammer m_h = {m_h:.4g} kg,",
        f"  m_eff = m_h M1/(m_h+M1) = {d['m_eff']:.5g} kg; target contact time t_c = {d['t_c']*1e3:.4g} ms,"
        f" zeta = {d['zeta']:.3g}",
        f"  omega_d = pi/t_c = {d['omega_d']:.6g} rad/s, omega_0 = omega_d/sqrt(1-zeta^2) = {d['omega_0']:.6g} rad/s",
        f"  k = m_eff omega_0^2 = {d['k']:.6g} N/m, c = 2 zeta sqrt(k m_eff) = {d['c']:.6g} N s/m"
        " (underdamped, not critical).",
        f"  Hammer-to-mode mass ratio m_h/M1 = {m_h/d['M1']:.4g}.",
    ]


# ----------------------------------------------------------------------------------------------
# TOML writing
# ----------------------------------------------------------------------------------------------

def ff(x, sig=7):
    """Format a float so that TOML reads it as a float (never as an integer)."""
    if not math.isfinite(x):
        raise ValueError(f"non-finite value {x}")
    s = f"{x:.{sig}g}"
    if not any(ch in s for ch in ".eE"):
        s += ".0"
    return s


def wrap_comment(lines):
    out = []
    for ln in lines:
        out.append("#" if ln == "" else "# " + ln)
    return "\n".join(out)


def write_scene(sc):
    """sc: dict(name, description, duration_s, header(list of str), object dict, hammer, contact, pickups)."""
    L = [wrap_comment(sc["header"]), ""]
    L.append("version = 1")
    L.append(f'name = "{sc["name"]}"')
    L.append(f'description = "{sc["description"]}"')
    L.append(f"duration_s = {ff(sc['duration_s'])}")
    L.append("")
    ob = sc["object"]
    L.append("[[object]]")
    L.append(f'name = "{ob["name"]}"')
    L.append('kind = "modal"')
    L.append("points = [" + ", ".join(f'"{p}"' for p in ob["points"]) + "]")
    for m in ob["modes"]:
        L.append("")
        if m.get("comment"):
            L.append("# " + m["comment"])
        L.append("[[object.mode]]")
        L.append(f"freq_hz = {ff(m['freq_hz'])}")
        L.append(f"t60_s = {ff(m['t60_s'], 5)}")
        L.append("weights = [" + ", ".join(ff(w, 6) for w in m["weights"]) + "]")
    h = sc["hammer"]
    L += ["", "[hammer]",
          f"mass_kg = {ff(h['mass_kg'])}",
          f"height_m = {ff(h['height_m'])}",
          f"velocity_m_per_s = {ff(h['velocity_m_per_s'])}",
          "gravity_m_per_s2 = 0.0"]
    c = sc["contact"]
    L += ["", "[contact]",
          f'object = "{ob["name"]}"',
          'point = "contact"',
          f"stiffness_n_per_m = {ff(c['stiffness_n_per_m'], 6)}",
          f"damping_n_s_per_m = {ff(c['damping_n_s_per_m'], 6)}"]
    for p in sc["pickups"]:
        L += ["", "[[pickup]]",
              f'object = "{ob["name"]}"',
              f'point = "{p["point"]}"',
              f'quantity = "{p["quantity"]}"',
              f"gain = {ff(p['gain'], 3)}"]
    text = "\n".join(L) + "\n"
    path = os.path.join(OUT_DIR, sc["name"] + ".toml")
    with open(path, "w") as fh:
        fh.write(text)
    return path


# ----------------------------------------------------------------------------------------------
# Impact simulation (independent of the Rust engine): used for gains and for the check printout
# ----------------------------------------------------------------------------------------------

def simulate(scene, t_end=0.1):
    """Return dict with first contact duration, contact count, hammer rebound velocity and pickup peaks.

    Flight/free phase: exact damped-oscillator steps of 1/(4 fs); when the coarse step would end in
    penetration, the step is redone with fine RK4 steps; contact phase: RK4 with dt_f."""
    ob = scene["object"][0]
    pts = ob["points"]
    ic = pts.index(scene["contact"]["point"])
    modes = ob["mode"]
    n = len(modes)
    om = [2 * math.pi * m["freq_hz"] for m in modes]
    al = [LN1000 / m["t60_s"] for m in modes]
    wc = [m["weights"][ic] for m in modes]
    pk_idx = [pts.index(p["point"]) for p in scene["pickup"]]
    wp = [[m["weights"][j] for m in modes] for j in pk_idx]
    qty = [p.get("quantity", "displacement") for p in scene["pickup"]]
    hm = scene["hammer"]
    m_h = hm["mass_kg"]
    g = hm.get("gravity_m_per_s2", 0.0)
    k = scene["contact"]["stiffness_n_per_m"]
    c = scene["contact"]["damping_n_s_per_m"]
    fmax = max(m["freq_hz"] for m in modes)
    fc = math.sqrt(k / m_h) / (2 * math.pi)
    dt_f = min(1.0 / (60.0 * fmax), 1.0 / (200.0 * fc), 1.0 / (40 * FS))
    dt_c = 1.0 / (4 * FS)

    # exact free propagator per mode for dt_c
    def prop(dt):
        P = []
        for i in range(n):
            w0, a = om[i], al[i]
            wd = math.sqrt(w0 * w0 - a * a)
            e, cs, sn = math.exp(-a * dt), math.cos(wd * dt), math.sin(wd * dt)
            P.append((e * (cs + a / wd * sn), e * sn / wd,
                      -e * w0 * w0 / wd * sn, e * (cs - a / wd * sn)))
        return P

    Pc = prop(dt_c)

    x = [0.0] * n
    v = [0.0] * n
    xh, vh = hm["height_m"], hm["velocity_m_per_s"]

    def xc_of(xs):
        return sum(wc[i] * xs[i] for i in range(n))

    def deriv(x, v, xh, vh):
        xcv = sum(wc[i] * x[i] for i in range(n))
        vcv = sum(wc[i] * v[i] for i in range(n))
        p = xcv - xh
        F = k * p + c * (vcv - vh) if p > 0 else 0.0
        ax = [-om[i] ** 2 * x[i] - 2 * al[i] * v[i] - wc[i] * F for i in range(n)]
        return v, ax, vh, F / m_h - g

    def rk4(x, v, xh, vh, h):
        k1 = deriv(x, v, xh, vh)
        x2 = [x[i] + 0.5 * h * k1[0][i] for i in range(n)]
        v2 = [v[i] + 0.5 * h * k1[1][i] for i in range(n)]
        k2 = deriv(x2, v2, xh + 0.5 * h * k1[2], vh + 0.5 * h * k1[3])
        x3 = [x[i] + 0.5 * h * k2[0][i] for i in range(n)]
        v3 = [v[i] + 0.5 * h * k2[1][i] for i in range(n)]
        k3 = deriv(x3, v3, xh + 0.5 * h * k2[2], vh + 0.5 * h * k2[3])
        x4 = [x[i] + h * k3[0][i] for i in range(n)]
        v4 = [v[i] + h * k3[1][i] for i in range(n)]
        k4 = deriv(x4, v4, xh + h * k3[2], vh + h * k3[3])
        xn = [x[i] + h / 6 * (k1[0][i] + 2 * k2[0][i] + 2 * k3[0][i] + k4[0][i]) for i in range(n)]
        vn = [v[i] + h / 6 * (k1[1][i] + 2 * k2[1][i] + 2 * k3[1][i] + k4[1][i]) for i in range(n)]
        return (xn, vn, xh + h / 6 * (k1[2] + 2 * k2[2] + 2 * k3[2] + k4[2]),
                vh + h / 6 * (k1[3] + 2 * k2[3] + 2 * k3[3] + k4[3]))

    def pick(x, v):
        return [sum(wp[j][i] * (v[i] if qty[j] == "velocity" else x[i]) for i in range(n))
                for j in range(len(wp))]

    t = 0.0
    peaks = [0.0] * len(wp)
    contacts = []  # (t_start, t_end)
    vh_after = None
    while t < t_end:
        # tentative exact free step (hammer in flight)
        xn = [Pc[i][0] * x[i] + Pc[i][1] * v[i] for i in range(n)]
        vn = [Pc[i][2] * x[i] + Pc[i][3] * v[i] for i in range(n)]
        xhn, vhn = xh + vh * dt_c - 0.5 * g * dt_c ** 2, vh - g * dt_c
        if xc_of(xn) - xhn <= 0 and xc_of(x) - xh <= 0:
            x, v, xh, vh, t = xn, vn, xhn, vhn, t + dt_c
        else:
            # fine RK4 through the contact
            in_c = xc_of(x) - xh > 0
            t_start = t if in_c else None
            t_enter = t
            while True:
                p_old = xc_of(x) - xh
                x, v, xh, vh = rk4(x, v, xh, vh, dt_f)
                t += dt_f
                p = xc_of(x) - xh
                for j, val in enumerate(pick(x, v)):
                    peaks[j] = max(peaks[j], abs(val))
                if t_start is None and p > 0:
                    t_start = t - dt_f * p / (p - p_old)
                if t_start is not None and p <= 0:
                    t_stop = t - dt_f * (-p) / (p_old - p)
                    contacts.append((t_start, t_stop))
                    if vh_after is None:
                        vh_after = vh
                    break
                if t_start is None and t > t_enter + 2 * dt_c:
                    break  # false alarm: grazing approach that separated again
                if t > t_end:
                    break
            # snap to the coarse grid again
            rem = (-t) % dt_c
            if rem > 1e-15:
                P = prop(rem)
                x, v = ([P[i][0] * x[i] + P[i][1] * v[i] for i in range(n)],
                        [P[i][2] * x[i] + P[i][3] * v[i] for i in range(n)])
                xh, vh, t = xh + vh * rem - 0.5 * g * rem ** 2, vh - g * rem, t + rem
            continue
        for j, val in enumerate(pick(x, v)):
            peaks[j] = max(peaks[j], abs(val))
    return dict(contacts=contacts, vh_after=vh_after, peaks=peaks)


# ----------------------------------------------------------------------------------------------
# 1. Marimba bar, A3
# ----------------------------------------------------------------------------------------------

def marimba():
    f1 = 220.0
    ratios_tuned = [1.0, 4.0, 10.0]
    rho, E, G = 1050.0, 20.0e9, 1.6e9  # Honduras rosewood, along the grain; G_LR ~ E/12
    Lb, b, h = 0.40, 0.058, 0.022  # A3 bar of a concert marimba (length, width, end thickness)
    arch_frac, t_arch = 0.55, 0.35  # arch over the central 55 % of the length, centre thickness 0.35 h
    lam = beam_roots(6)
    bm = [BeamMode(l, "free") for l in lam]
    c_l = math.sqrt(E / rho)
    f_uni = [l ** 2 / (2 * math.pi * Lb ** 2) * h / math.sqrt(12) * c_l for l in lam]

    # Rayleigh quotient of the arched bar with the uniform-bar shape as trial function:
    # f/f_uni = sqrt((1 - Fs + t^3 Fs) / (1 - Fk + t Fk)), Fs, Fk = share of int psi''^2, psi^2 in the arch
    a0, a1 = 0.5 - arch_frac / 2, 0.5 + arch_frac / 2

    def share(fun):
        tot = simpson(fun, 4000)
        part = simpson(lambda u: fun(a0 + u * (a1 - a0)), 2000) * (a1 - a0)
        return part / tot

    def rayleigh(Fs, Fk):
        return math.sqrt((1 - Fs + t_arch ** 3 * Fs) / (1 - Fk + t_arch * Fk))

    ray_b1 = rayleigh(share(lambda xi: bm[0].psi2(xi) ** 2), share(lambda xi: bm[0].psi(xi) ** 2))
    m_uniform = rho * Lb * b * h
    m_b = m_uniform * (1 - arch_frac * (1 - t_arch))

    # tuned modes 1-3; untuned 4-6: tuning factors (tuned/uniform) extrapolated towards 1
    fac = [ratios_tuned[i] * f1 / f_uni[i] for i in range(3)]
    r = (1 - fac[2]) / (1 - fac[1])
    for n in range(3, 6):
        fac.append(1 - (1 - fac[2]) * r ** (n - 2))
    f_bend = [fac[i] * f_uni[i] for i in range(6)]

    # torsion (free-free): theta_n = A cos(n pi xi), f_n = n c_t / (2L) for the uniform bar
    beta_t = torsion_beta(b / h)
    Kt, Jp = beta_t * b * h ** 3, b * h * (b * b + h * h) / 12.0
    c_t = math.sqrt(G / rho) * math.sqrt(Kt / Jp)
    f_tor_uni = [n * c_t / (2 * Lb) for n in (1, 2)]
    f_tor = []
    for n in (1, 2):
        Fs = share(lambda xi: math.sin(n * math.pi * xi) ** 2)
        Fk = share(lambda xi: math.cos(n * math.pi * xi) ** 2)
        f_tor.append(f_tor_uni[n - 1] * rayleigh(Fs, Fk))
    A_t = math.sqrt(24.0 / (m_b * (b * b + h * h)))  # mass normalisation: int rho J_p theta^2 dx = 1

    # damping: alpha = alpha0 + pi f eta
    eta, alpha0 = 0.0075, 0.5

    def t60(f):
        return t60_from_alpha(alpha0 + math.pi * f * eta)

    xc, yc = 0.45, 0.25 * b  # contact: slightly off centre (x/L) and off the centre line (m)
    xp, yp = 0.06, -0.20 * b  # pickup: near one end, other side of the centre line

    modes = []
    names = ["bending 1 (tuned fundamental, A3)", "bending 2 (tuned 4:1, two octaves)",
             "bending 3 (tuned 10:1, three octaves + major third)", "bending 4 (untuned)",
             "bending 5 (untuned)", "bending 6 (untuned)"]
    allm = []
    for i in range(6):
        w = [bm[i].psi(xc) / math.sqrt(m_b), bm[i].psi(xp) / math.sqrt(m_b)]
        allm.append((f_bend[i], w, names[i] + f", ratio {f_bend[i]/f1:.3f}"))
    for n in (1, 2):
        w = [yc * A_t * math.cos(n * math.pi * xc), yp * A_t * math.cos(n * math.pi * xp)]
        allm.append((f_tor[n - 1], w, f"torsion {n}, ratio {f_tor[n-1]/f1:.3f}"))
    allm.sort(key=lambda m: m[0])
    for f, w, cm in allm:
        modes.append(dict(freq_hz=f, t60_s=t60(f), weights=w, comment=cm))

    m_h, t_c, zeta, v0 = 0.030, 1.0e-3, 0.25, -2.0
    d = design_contact(m_h, modes[0]["weights"][0], t_c, zeta)

    hdr = [
        "marimba-bar: one rosewood marimba bar, A3 (220 Hz), struck by a yarn mallet.",
        "Generated by presets/tools/gen_presets.py (edit the script, not this file).",
        "",
        "Bar: Honduras rosewood, rho = 1050 kg/m^3, E_L = 20 GPa, G_LR = 1.6 GPa (~E/12, assumed);",
        f"length L = {Lb} m, width b = {b} m, end thickness h = {h} m (typical A3 concert-marimba bar).",
        f"Uniform free-free bar: f_n = lambda_n^2/(2 pi L^2) * h/sqrt(12) * sqrt(E/rho), lambda_n = "
        + ", ".join(f"{l:.4f}" for l in lam[:4]) + ", ...",
        "  -> f_uni = " + ", ".join(f"{f:.0f}" for f in f_uni) + " Hz (ratios 1 : 2.756 : 5.404 : 8.933 ...).",
        "The undercut (arch) lowers and retunes the modes. Marimba makers tune the first three bending modes",
        "1 : 4 : 10 (two octaves; three octaves + a major third), xylophones 1 : 3 (Fletcher & Rossing,",
        "The Physics of Musical Instruments, 2nd ed., ch. 19; Bork, Acustica 1995; hyperphysics 'xylo').",
        "  -> bending 1-3 = " + ", ".join(f"{f:.1f}" for f in f_bend[:3]) + " Hz (tuning factors "
        + ", ".join(f"{x:.3f}" for x in fac[:3]) + " of the uniform bar).",
        "Untuned bending 4-6: the arch lowers high modes less; the factor is extrapolated geometrically",
        f"towards 1: 1 - (1 - {fac[2]:.3f}) * {r:.3f}^(n-3) -> " + ", ".join(f"{x:.3f}" for x in fac[3:])
        + " -> " + ", ".join(f"{f:.0f}" for f in f_bend[3:]) + " Hz (estimate, +-10 %).",
        f"Arch model (used for the mass and the torsion estimate only): the central {arch_frac:.0%} of the length",
        f"  thinned to t = {t_arch} h (a deep low-register arch, idealised as uniform depth). Bar mass",
        f"  m_b = rho L b h (1 - {arch_frac} (1 - t)) = {m_uniform:.4f} * {m_b/m_uniform:.3f} = {m_b:.4f} kg.",
        f"  Rayleigh quotient of this arch with the uniform mode 1 as trial shape: f1/f_uni <= {ray_b1:.3f}",
        f"  (an upper bound; the shape change lowers it further, and the maker shapes the arch until",
        f"  f1/f_uni = {f1/f_uni[0]:.3f} and the 1:4:10 tuning is reached).",
        f"Torsion (free-free): f_n = n c_t/(2L), c_t = sqrt(G/rho) sqrt(K_t/J_p), K_t = beta b h^3 (beta ="
        f" {beta_t:.4f}),",
        f"  J_p = b h (b^2+h^2)/12 -> c_t = {c_t:.1f} m/s, uniform f_t = " + ", ".join(f"{f:.0f}" for f in f_tor_uni)
        + " Hz; the arch (K_t ~ h^3 where the twist",
        "  is largest) lowers them by the same Rayleigh-quotient factor to " + ", ".join(f"{f:.0f}" for f in f_tor)
        + " Hz (crude estimate).",
        "",
        "Weights: uniform-bar Euler-Bernoulli shapes (approximation: the arch changes the shapes somewhat),",
        "  phi_n(x) = psi_n(x)/sqrt(m_b), psi_n = cosh + cos - sigma_n (sinh + sin) of lambda_n x/L,",
        "  normalised to mean square 1 over the length (psi_n = +-2 at the ends);",
        "  torsion: w = y A cos(n pi x/L), A = sqrt(24/(m_b (b^2+h^2))) so that int rho J_p theta^2 dx = 1.",
        f"Points: contact at x = {xc} L, y = +{yc*1e3:.1f} mm (off centre, as players strike);",
        f"        pickup  at x = {xp} L, y = {yp*1e3:.1f} mm (near an end: every mode is present there).",
        "",
        f"T60: alpha = alpha0 + pi f eta (amplitude decay rate), eta = {eta} (rosewood loss factor,",
        f"  Q ~ {1/eta:.0f}; literature 0.006-0.01), alpha0 = {alpha0} 1/s (cord supports, radiation);",
        f"  T60 = ln(1000)/alpha -> {t60(f1):.2f} s at {f1:.0f} Hz, {t60(4*f1):.2f} s at {4*f1:.0f} Hz,"
        f" {t60(10*f1):.3f} s at {10*f1:.0f} Hz.",
        "  No resonator tube is modelled (a tuned tube would radiate the fundamental more strongly and",
        "  so shorten its decay somewhat).",
        "",
        f"Mallet: yarn-wound rubber-core marimba mallet, effective head mass {m_h} kg, contact time ~1 ms",
        f"  (soft mallets: 0.5-2 ms), zeta = {zeta} (yarn is lossy), starts {1.0} mm above the bar at {v0} m/s,",
        "  no gravity.",
    ] + contact_comment(d, m_h)
    return dict(name="marimba-bar",
                description="Rosewood marimba bar A3 (220 Hz), bending modes tuned 1:4:10, yarn mallet",
                duration_s=2.5, header=hdr,
                object=dict(name="bar", points=["contact", "pickup"], modes=modes),
                hammer=dict(mass_kg=m_h, height_m=1.0e-3, velocity_m_per_s=v0),
                contact=dict(stiffness_n_per_m=d["k"], damping_n_s_per_m=d["c"], zeta=zeta, t_c=t_c),
                pickups=[dict(point="pickup", quantity="velocity", gain=1.0)])


# ----------------------------------------------------------------------------------------------
# 2. Simply supported steel plate
# ----------------------------------------------------------------------------------------------

def steel_plate():
    E, nu, rho = 200.0e9, 0.30, 7850.0
    a, b, h = 0.40, 0.28, 0.008
    fmax = 8000.0
    D = E * h ** 3 / (12 * (1 - nu ** 2))
    rho_s = rho * h
    M = rho_s * a * b
    cplate = math.sqrt(D / rho_s)
    # coincidence frequency and radiation damping of an infinite plate above it
    f_co = C_AIR ** 2 / (2 * math.pi) * math.sqrt(rho_s / D)
    alpha_rad_inf = RHO_AIR * C_AIR / (2 * rho_s)
    eta, alpha0 = 1.0e-4, 0.3
    lam_c, P, S = C_AIR / f_co, 2 * (a + b), a * b
    sigma_c = math.sqrt(a / lam_c) + math.sqrt(b / lam_c)

    def sigma(f):
        """Radiation efficiency of a baffled simply supported plate: Maidanik (1962) as given in
        Beranek & Ver, Noise and Vibration Control Engineering (1992), capped at the coincidence value."""
        if f >= f_co:
            s = 1.0 / math.sqrt(1.0 - f_co / f) if f > f_co else float("inf")
        else:
            al = math.sqrt(f / f_co)
            g2 = ((1 - al * al) * math.log((1 + al) / (1 - al)) + 2 * al) / (4 * math.pi ** 2 * (1 - al * al) ** 1.5)
            g1 = 4 / math.pi ** 4 * (1 - 2 * al * al) / (al * math.sqrt(1 - al * al)) if f < f_co / 2 else 0.0
            s = lam_c * P / S * g2 + 2 * lam_c ** 2 / S * g1
        return min(s, sigma_c)

    def alpha(f):
        return alpha0 + math.pi * f * eta + alpha_rad_inf * sigma(f)

    pts = {"contact": (0.37, 0.41), "pickup": (0.72, 0.64), "pickup2": (0.19, 0.79)}
    mlist = []
    for m in range(1, 40):
        for n in range(1, 40):
            f = math.pi / 2 * cplate * ((m / a) ** 2 + (n / b) ** 2)
            if f < fmax:
                mlist.append((f, m, n))
    mlist.sort()
    k8 = math.sqrt(2 * math.pi * fmax / cplate)
    n8 = a * b * k8 ** 2 / (4 * math.pi) - 2 * (a + b) * k8 / (4 * math.pi)
    mind8 = 1 - 0.5 * (k8 * h / math.sqrt(12)) ** 2 * (1 + 2 / (math.pi ** 2 / 12 * (1 - nu)))
    modes = []
    for f, m, n in mlist:
        w = [2 / math.sqrt(M) * math.sin(m * math.pi * x) * math.sin(n * math.pi * y)
             for (x, y) in pts.values()]
        modes.append(dict(freq_hz=f, t60_s=t60_from_alpha(alpha(f)), weights=w,
                          comment=f"mode (m, n) = ({m}, {n})"))
    # hard beater: brass or hard-plastic head; Hertz estimates bracket the chosen 0.2 ms
    m_h, t_c, zeta, v0 = 0.040, 0.2e-3, 0.10, -1.5
    R_head = 0.012
    t_brass = hertz_contact_time(m_h, R_head, e_star(E, nu, 100e9, 0.34), -v0)
    t_plastic = hertz_contact_time(m_h, R_head, e_star(E, nu, 3.0e9, 0.35), -v0)
    d = design_contact(m_h, modes[0]["weights"][0], t_c, zeta)
    ex = modes[0]["freq_hz"]
    hdr = [
        "steel-plate: simply supported rectangular steel plate (e.g. bolted in a frame), hard beater.",
        "Generated by presets/tools/gen_presets.py (edit the script, not this file).",
        "",
        f"Plate: a = {a} m, b = {b} m, h = {h} m; structural steel E = {E/1e9:.0f} GPa, nu = {nu},"
        f" rho = {rho:.0f} kg/m^3.",
        f"D = E h^3 / (12 (1 - nu^2)) = {D:.1f} N m, rho h = {rho_s:.2f} kg/m^2, M = rho h a b = {M:.3f} kg.",
        "Kirchhoff plate, simply supported on all edges (Leissa, Vibration of Plates, NASA SP-160):",
        "  f_mn = (pi/2) sqrt(D/(rho h)) ((m/a)^2 + (n/b)^2),"
        f" sqrt(D/(rho h)) = {cplate:.3f} m^2/s -> f_11 = {ex:.2f} Hz.",
        f"All {len(modes)} modes below {fmax:.0f} Hz are kept (mode count with edge correction for simple",
        f"  supports: N ~ S k^2/(4 pi) - P k/(4 pi), k = sqrt(2 pi f / sqrt(D/rho h)) = {k8:.1f} 1/m -> {n8:.1f}).",
        f"  Mindlin shear/rotary-inertia correction, 1 - (k r)^2 (1 + 2/(kappa (1-nu)))/2 with r = h/sqrt(12),",
        f"  kappa = pi^2/12, would lower the top mode by {100*(1-mind8):.1f} %; neglected, as in the formula above.",
        "Mass-normalised shapes: phi_mn(x, y) = 2/sqrt(M) sin(m pi x/a) sin(n pi y/b)"
        f" (max |w| = {2/math.sqrt(M):.4f} 1/sqrt(kg), i.e. M/4 = {M/4:.3f} kg).",
        "Points (x/a, y/b): contact (0.37, 0.41) off-centre so that few low modes sit on a nodal line;",
        "  pickup (0.72, 0.64) and pickup2 (0.19, 0.79): two velocity pickups (a stereo pair).",
        "",
        "T60: alpha(f) = alpha0 + pi f eta + alpha_rad(f) (amplitude decay rate), T60 = ln(1000)/alpha:",
        f"  alpha0 = {alpha0} 1/s (edge supports), eta = {eta} (steel internal loss),",
        f"  alpha_rad = rho0 c/(2 rho h) sigma(f), rho0 c/(2 rho h) = {alpha_rad_inf:.3f} 1/s (air 1.204 kg/m^3, 343 m/s),",
        f"  coincidence f_co = c^2/(2 pi) sqrt(rho h/D) = {f_co:.0f} Hz, lambda_c = c/f_co = {lam_c:.3f} m;",
        "  sigma = radiation efficiency of a baffled simply supported plate (Maidanik 1962, as in Beranek &",
        "  Ver 1992): below f_co sigma = lambda_c P/S g2 + 2 lambda_c^2/S g1 (edge and corner radiation,",
        "  alpha = sqrt(f/f_co), g2 = ((1-alpha^2) ln((1+alpha)/(1-alpha)) + 2 alpha)/(4 pi^2 (1-alpha^2)^1.5),",
        "  g1 = 4/pi^4 (1-2alpha^2)/(alpha sqrt(1-alpha^2)) below f_co/2), above f_co sigma = 1/sqrt(1-f_co/f),",
        f"  both capped at sqrt(a/lambda_c) + sqrt(b/lambda_c) = {sigma_c:.2f}. sigma = "
        + ", ".join(f"{sigma(mm[0]):.2f}" for mm in mlist[:6]) + " ... for the lowest modes.",
        "  Radiation makes the decay fastest near coincidence (T60 minimum ~0.8 s at 1.3-1.6 kHz); above it",
        "  sigma falls towards 1 and T60 recovers to ~1.2 s before the material term slowly takes over",
        "  (so T60 is not monotonic in f here: that is the coincidence dip, not a typo).",
        f"  -> T60 = {t60_from_alpha(alpha(ex)):.1f} s at {ex:.0f} Hz ... "
        f"{modes[-1]['t60_s']:.2f} s at {modes[-1]['freq_hz']:.0f} Hz.",
        "",
        f"Beater: hard (brass or phenolic) head, effective mass {m_h} kg, radius ~{R_head*1e3:.0f} mm, {v0} m/s.",
        f"  Hertz contact time t = 2.868 (m^2/(R E*^2 v))^(1/5): brass head {t_brass*1e3:.3f} ms,"
        f" hard-plastic head {t_plastic*1e3:.3f} ms;",
        f"  we take t_c = {t_c*1e3} ms (linear spring matched at this velocity), zeta = {zeta}.",
    ] + contact_comment(d, m_h)
    return dict(name="steel-plate",
                description="Simply supported 400 x 280 x 8 mm steel plate, all modes below 8 kHz, hard beater",
                duration_s=6.0, header=hdr,
                object=dict(name="plate", points=list(pts.keys()), modes=modes),
                hammer=dict(mass_kg=m_h, height_m=1.0e-3, velocity_m_per_s=v0),
                contact=dict(stiffness_n_per_m=d["k"], damping_n_s_per_m=d["c"], zeta=zeta, t_c=t_c),
                pickups=[dict(point="pickup", quantity="velocity", gain=1.0),
                         dict(point="pickup2", quantity="velocity", gain=1.0)])


# ----------------------------------------------------------------------------------------------
# 3. Bell
# ----------------------------------------------------------------------------------------------

def bell():
    prime = 880.0  # A5 strike note / prime; nominal 1760 Hz
    nominal = 2 * prime
    D_in = 0.50 / 0.0254
    C_w, U_w = 3.0, 4359085.0
    W_lb = C_w * nominal * D_in ** 4 / U_w
    m_bell = W_lb * 0.45359237
    # (name, (m, n), ratio to prime, r = mean-square meridional displacement / value at the soundbow)
    plist = [
        ("hum", "(2,0)", 0.5, 2, 0.50),
        ("prime (strike)", "(2,1#)", 1.0, 2, 0.35),
        ("tierce (minor third)", "(3,1)", 1.2, 3, 0.30),
        ("quint (fifth)", "(3,1#)", 1.5, 3, 0.25),
        ("nominal (octave)", "(4,1)", 2.0, 4, 0.20),
        ("deciem (major tenth)", "(4,1#)", 2.5, 4, 0.18),
        ("superquint (twelfth)", "(5,1)", 3.0, 5, 0.15),
        ("octave nominal", "(6,1)", 4.1, 6, 0.13),
        ("upper partial I-7", "(7,1)", 5.2, 7, 0.12),
        ("upper partial I-8", "(8,1)", 6.4, 8, 0.11),
    ]
    theta_p = math.radians(100.0)
    eta, alpha0 = 2.0e-4, 0.05

    def t60(f):
        return t60_from_alpha(alpha0 + math.pi * f * eta)

    modes = []
    rows = []
    for name, mn, ratio, m, r in plist:
        f = ratio * prime
        Mi = m_bell * 0.5 * (1 + 1.0 / m ** 2) * r
        wc = 1 / math.sqrt(Mi)
        wp = wc * math.cos(m * theta_p)
        modes.append(dict(freq_hz=f, t60_s=t60(f), weights=[wc, wp],
                          comment=f"{name} {mn}, {ratio} x prime, M_eff = {Mi:.2f} kg"))
        rows.append(f"  {name:22s} {mn:7s} {ratio:4.2f} x  {f:7.1f} Hz  m={m}  r={r:.2f}  M_eff={Mi:6.2f} kg"
                    f"  cos(m*100deg)={math.cos(m*theta_p):+.3f}")
    # clapper
    m_clapper = m_bell / 35.0
    m_h = round(0.7 * m_clapper, 2)
    v0, zeta = -1.2, 0.10
    R_ball = 0.030
    Es = e_star(190e9, 0.28, 105e9, 0.34)
    M1 = 1.0 / modes[0]["weights"][0] ** 2
    m_red = m_h * M1 / (m_h + M1)
    t_hertz = hertz_contact_time(m_red, R_ball, Es, -v0)
    t_c = round(t_hertz * 1e5) / 1e5
    d = design_contact(m_h, modes[0]["weights"][0], t_c, zeta)
    hdr = [
        "bell: small bronze church (chapel) bell, strike note / prime A5 = 880 Hz, struck by its clapper.",
        "Generated by presets/tools/gen_presets.py (edit the script, not this file).",
        "",
        "Partials of a true-harmonic (Simpson/Taylor-tuned) church bell relative to the prime:",
        "hum 0.5, prime 1, tierce 1.2, quint 1.5, nominal 2 (Rossing & Perrin, Applied Acoustics 20 (1987) 41;",
        "Fletcher & Rossing ch. 21); higher (m,1) partials are stretched above harmonic: deciem 2.5,",
        "superquint ~3.0, octave nominal ~4.1, I-7 ~5.2, I-8 ~6.4 (typical; they vary bell to bell).",
        "(m, n): m = half the number of nodal meridians, n = nodal circles ('#' = circle near the soundbow).",
        "",
        "Bell mass from the founders' rule W[lb] = C f_nominal D[in]^4 / 4359085 (C = 3 modern bells):",
        f"  mouth diameter D = 0.50 m, nominal {nominal:.0f} Hz -> W = {W_lb:.1f} lb = {m_bell:.1f} kg (bell bronze"
        " 78 Cu/22 Sn).",
        "Weights from effective (apparent) modal masses at the strike point on the soundbow:",
        "  M_i = m_bell * 1/2 * (1 + 1/m^2) * r_i,   w_c,i = 1/sqrt(M_i)  (positive at the strike point)",
        "  1/2: circumferential mean of cos^2(m theta); (1 + 1/m^2): inextensional shell modes carry a",
        "  tangential motion u_theta = u_r/m (Rayleigh), adding kinetic energy; r_i: mean-square meridional",
        "  displacement relative to the soundbow value (estimate: the hum moves the whole waist, higher",
        "  modes concentrate at the lip, so r falls from 0.5 to ~0.1).",
        "Each (m,n) mode is a degenerate pair (cos m theta, sin m theta); striking at theta = 0 excites only",
        "  the cos member, so one mode per partial is listed.",
        "Pickup: on the soundbow at azimuth 100 deg from the strike point: w_p,i = w_c,i cos(m * 100 deg)",
        "  (100 deg keeps every m = 2..8 away from a nodal meridian except m = 8, which is weak anyway).",
    ] + rows + [
        "",
        f"T60: alpha = alpha0 + pi f eta, eta = {eta} (bell bronze, Q ~ {1/eta:.0f}, incl. radiation),"
        f" alpha0 = {alpha0} 1/s (headstock);",
        f"  T60 = ln(1000)/alpha -> hum {t60(0.5*prime):.1f} s (longest), prime {t60(prime):.1f} s, nominal"
        f" {t60(nominal):.1f} s, I-8 {t60(6.4*prime):.2f} s.",
        "",
        f"Clapper: ~1/35 of the bell mass ({m_clapper:.2f} kg); effective mass at the ball of the pendulum"
        f" ~0.7 of it -> m_h = {m_h} kg,",
        f"  hitting at {v0} m/s (the engine's axis is the strike direction, no gravity).",
        f"  Hertz estimate, iron ball R = {R_ball*1e3:.0f} mm on bronze (E* = {Es/1e9:.1f} GPa), reduced mass"
        f" {m_red:.3f} kg: t_c = {t_hertz*1e3:.3f} ms",
        f"  -> t_c = {t_c*1e3:.2f} ms; zeta = {zeta} (metal on metal, little loss).",
    ] + contact_comment(d, m_h)
    return dict(name="bell",
                description="Small bronze church bell (prime A5 880 Hz, 0.5 m, ~80 kg): hum, prime, tierce, quint,"
                            " nominal and upper partials; iron clapper",
                duration_s=12.0, header=hdr,
                object=dict(name="bell", points=["contact", "pickup"], modes=modes),
                hammer=dict(mass_kg=m_h, height_m=1.0e-3, velocity_m_per_s=v0),
                contact=dict(stiffness_n_per_m=d["k"], damping_n_s_per_m=d["c"], zeta=zeta, t_c=t_c),
                pickups=[dict(point="pickup", quantity="velocity", gain=1.0)])


# ----------------------------------------------------------------------------------------------
# 4. Wood block
# ----------------------------------------------------------------------------------------------

def wood_block():
    rho, E, G = 700.0, 12.0e9, 1.1e9  # hard maple along the grain; G_LR ~ 1.1 GPa
    Lb, b, h = 0.25, 0.060, 0.010
    lam = beam_roots(3)
    bm = [BeamMode(l, "clamped") for l in lam]
    c_l = math.sqrt(E / rho)
    f_eb = [l ** 2 / (2 * math.pi * Lb ** 2) * h / math.sqrt(12) * c_l for l in lam]
    tf = [timoshenko_factor(l / Lb, h, E, G) for l in lam]
    f_b = [f_eb[i] * tf[i] for i in range(3)]
    beta_t = torsion_beta(b / h)
    Kt, Jp = beta_t * b * h ** 3, b * h * (b * b + h * h) / 12.0
    c_t = math.sqrt(G / rho) * math.sqrt(Kt / Jp)
    f_t = [n * c_t / (2 * Lb) for n in (1, 2)]
    m_lip = rho * Lb * b * h
    A_t = math.sqrt(24.0 / (m_lip * (b * b + h * h)))
    eta, alpha0 = 0.011, 5.0

    def t60(f):
        return t60_from_alpha(alpha0 + math.pi * f * eta)

    xc, yc = 0.45, 0.30 * b
    xp, yp = 0.30, -0.25 * b
    allm = []
    for i in range(3):
        allm.append((f_b[i], [bm[i].psi(xc) / math.sqrt(m_lip), bm[i].psi(xp) / math.sqrt(m_lip)],
                     f"bending {i+1} (clamped-clamped)"))
    for n in (1, 2):
        allm.append((f_t[n - 1], [yc * A_t * math.sin(n * math.pi * xc), yp * A_t * math.sin(n * math.pi * xp)],
                     f"torsion {n} (clamped-clamped)"))
    allm.sort(key=lambda m: m[0])
    modes = [dict(freq_hz=f, t60_s=t60(f), weights=w, comment=cm + f", ratio {f/allm[0][0]:.3f}")
             for f, w, cm in allm]
    m_h, t_c, zeta, v0 = 0.008, 0.25e-3, 0.10, -1.5
    d = design_contact(m_h, modes[0]["weights"][0], t_c, zeta)
    hdr = [
        "wood-block: hardwood slit (Chinese) wood block struck on the thin top wall above the slot.",
        "Generated by presets/tools/gen_presets.py (edit the script, not this file).",
        "",
        "Model: the struck top wall (the 'lip' over the slot) is a maple strip clamped at both ends by the",
        f"solid end walls: L = {Lb} m, b = {b} m, h = {h} m; hard maple rho = {rho:.0f} kg/m^3, E_L ="
        f" {E/1e9:.0f} GPa, G_LR = {G/1e9} GPa.",
        f"Lip mass m = rho L b h = {m_lip*1e3:.2f} g. Its (flexural and torsional) modes dominate the 'tock';",
        "the cavity (Helmholtz) resonance and the heavy block body are not modelled.",
        "Bending, clamped-clamped Euler-Bernoulli: f_n = lambda_n^2/(2 pi L^2) h/sqrt(12) sqrt(E/rho),",
        "  lambda_n = " + ", ".join(f"{l:.4f}" for l in lam) + " -> " + ", ".join(f"{f:.0f}" for f in f_eb) + " Hz;",
        "  wood is soft in shear (E/G ~ 11), so the first-order Timoshenko correction",
        "  f_T/f_EB = 1 - (k r)^2 (1 + E/(kappa G))/2, k = lambda_n/L, r = h/sqrt(12), kappa = 5/6, gives factors "
        + ", ".join(f"{x:.3f}" for x in tf),
        "  -> " + ", ".join(f"{f:.0f}" for f in f_b) + " Hz.",
        f"Torsion, clamped-clamped: f_n = n c_t/(2L), c_t = sqrt(G/rho) sqrt(K_t/J_p), K_t = beta b h^3"
        f" (beta = {beta_t:.4f}),",
        f"  J_p = b h (b^2+h^2)/12 -> c_t = {c_t:.1f} m/s -> " + ", ".join(f"{f:.0f}" for f in f_t) + " Hz.",
        "Inharmonic ratios: " + " : ".join(f"{m['freq_hz']/modes[0]['freq_hz']:.3f}" for m in modes) + ".",
        "Weights: psi_n = cosh - cos - sigma_n (sinh - sin) of lambda_n x/L (mean square 1), w = psi_n/sqrt(m);",
        "  torsion w = y A sin(n pi x/L), A = sqrt(24/(m (b^2+h^2))).",
        f"Points: contact at x = {xc} L, y = +{yc*1e3:.1f} mm (near the middle, towards the slot edge);"
        f" pickup at x = {xp} L, y = {yp*1e3:.2f} mm.",
        "",
        f"T60: alpha = alpha0 + pi f eta, eta = {eta} (maple ~0.008 plus radiation and cavity losses),",
        f"  alpha0 = {alpha0} 1/s (energy lost into the block body and the player's hand) ->"
        f" T60 = {modes[0]['t60_s']:.3f} s ... {modes[-1]['t60_s']:.3f} s.",
        "",
        f"Stick: hickory drumstick tip, effective mass at the tip ~ I/l^2 ~ 1/6 of a 48 g stick -> {m_h} kg,",
        f"  {v0} m/s; wood on wood t_c = {t_c*1e3} ms, zeta = {zeta}.",
    ] + contact_comment(d, m_h)
    return dict(name="wood-block",
                description="Maple slit wood block: clamped lip, 3 bending + 2 torsion modes, strongly damped,"
                            " light stick",
                duration_s=0.6, header=hdr,
                object=dict(name="block", points=["contact", "pickup"], modes=modes),
                hammer=dict(mass_kg=m_h, height_m=1.0e-3, velocity_m_per_s=v0),
                contact=dict(stiffness_n_per_m=d["k"], damping_n_s_per_m=d["c"], zeta=zeta, t_c=t_c),
                pickups=[dict(point="pickup", quantity="velocity", gain=1.0)])


# ----------------------------------------------------------------------------------------------
# 5. Glockenspiel bar (extra)
# ----------------------------------------------------------------------------------------------

def glockenspiel():
    f1 = 1760.0  # A6
    rho, E, G, nu = 2700.0, 70.0e9, 26.0e9, 0.33  # aluminium alloy (6061 / 6082)
    b, h = 0.030, 0.008
    lam = beam_roots(5)
    bm = [BeamMode(l, "free") for l in lam]
    c_l = math.sqrt(E / rho)

    def freqs(Lb):
        return [l ** 2 / (2 * math.pi * Lb ** 2) * h / math.sqrt(12) * c_l * timoshenko_factor(l / Lb, h, E, G)
                for l in lam]

    Lb = bisect(lambda L: freqs(L)[0] - f1, 0.05, 0.5)
    f_eb = [l ** 2 / (2 * math.pi * Lb ** 2) * h / math.sqrt(12) * c_l for l in lam]
    tf = [timoshenko_factor(l / Lb, h, E, G) for l in lam]
    f_b = freqs(Lb)
    m_b = rho * Lb * b * h
    beta_t = torsion_beta(b / h)
    Kt, Jp = beta_t * b * h ** 3, b * h * (b * b + h * h) / 12.0
    c_t = math.sqrt(G / rho) * math.sqrt(Kt / Jp)
    f_t = [n * c_t / (2 * Lb) for n in (1, 2, 3)]
    A_t = math.sqrt(24.0 / (m_b * (b * b + h * h)))
    eta, alpha0 = 3.0e-4, 0.4

    def t60(f):
        return t60_from_alpha(alpha0 + math.pi * f * eta)

    xc, yc = 0.45, 0.20 * b
    xp, yp = 0.04, -0.25 * b
    allm = []
    for i in range(5):
        if f_b[i] < 20000:
            allm.append((f_b[i], [bm[i].psi(xc) / math.sqrt(m_b), bm[i].psi(xp) / math.sqrt(m_b)],
                         f"bending {i+1}"))
    for n in (1, 2, 3):
        if f_t[n - 1] < 20000:
            allm.append((f_t[n - 1], [yc * A_t * math.cos(n * math.pi * xc), yp * A_t * math.cos(n * math.pi * xp)],
                         f"torsion {n}"))
    allm.sort(key=lambda m: m[0])
    modes = [dict(freq_hz=f, t60_s=t60(f), weights=w, comment=cm + f", ratio {f/f1:.3f}") for f, w, cm in allm]
    m_h, t_c, zeta, v0 = 0.020, 0.25e-3, 0.10, -1.5
    d = design_contact(m_h, modes[0]["weights"][0], t_c, zeta)
    hdr = [
        "glockenspiel-bar: one aluminium glockenspiel bar, A6 (1760 Hz), hard plastic mallet.",
        "Generated by presets/tools/gen_presets.py (edit the script, not this file).",
        "",
        f"Bar: uniform (no undercut) aluminium alloy, rho = {rho:.0f} kg/m^3, E = {E/1e9:.0f} GPa,"
        f" G = {G/1e9:.0f} GPa; width b = {b} m, thickness h = {h} m.",
        "Free-free Euler-Bernoulli: f_n = lambda_n^2/(2 pi L^2) h/sqrt(12) sqrt(E/rho), ratios 1 : 2.756 :"
        " 5.404 : 8.933 : 13.34,",
        "  with the first-order Timoshenko (shear + rotary inertia) factor 1 - (k r)^2 (1 + E/(kappa G))/2",
        "  (k = lambda_n/L, r = h/sqrt(12), kappa = 5/6): " + ", ".join(f"{x:.4f}" for x in tf) + ".",
        f"L solved so that the corrected f_1 = {f1:.0f} Hz: L = {Lb*1e3:.1f} mm, mass m_b = {m_b*1e3:.1f} g.",
        "  EB: " + ", ".join(f"{f:.0f}" for f in f_eb) + " Hz; corrected: " + ", ".join(f"{f:.0f}" for f in f_b)
        + " Hz (>= 20 kHz dropped);",
        f"  so the overtones of a thick bar sit below the ideal 2.756 / 5.404: here 1 : {f_b[1]/f_b[0]:.3f} :"
        f" {f_b[2]/f_b[0]:.3f}.",
        f"Torsion: f_n = n c_t/(2L), c_t = sqrt(G/rho) sqrt(K_t/J_p), K_t = beta b h^3 (beta = {beta_t:.4f}),",
        f"  J_p = b h (b^2+h^2)/12 -> c_t = {c_t:.0f} m/s -> " + ", ".join(f"{f:.0f}" for f in f_t) + " Hz.",
        "Weights: psi_n = cosh + cos - sigma_n (sinh + sin) (mean square 1), w = psi_n/sqrt(m_b);",
        "  torsion w = y A cos(n pi x/L), A = sqrt(24/(m_b (b^2+h^2))).",
        f"Points: contact x = {xc} L, y = +{yc*1e3:.1f} mm (just off centre); pickup x = {xp} L,"
        f" y = {yp*1e3:.1f} mm (near an end).",
        "",
        f"T60: alpha = alpha0 + pi f eta, eta = {eta} (aluminium + radiation), alpha0 = {alpha0} 1/s"
        " (felt/pin supports at the nodes)",
        f"  -> T60 = {modes[0]['t60_s']:.2f} s at {f1:.0f} Hz ... {modes[-1]['t60_s']:.2f} s at"
        f" {modes[-1]['freq_hz']:.0f} Hz.",
        "",
        f"Mallet: hard plastic (acetal) head, effective mass {m_h} kg, {v0} m/s, t_c = {t_c*1e3} ms, zeta = {zeta}.",
    ] + contact_comment(d, m_h)
    return dict(name="glockenspiel-bar",
                description="Aluminium glockenspiel bar A6 (1760 Hz), free-free bending + torsion modes,"
                            " hard plastic mallet",
                duration_s=4.0, header=hdr,
                object=dict(name="bar", points=["contact", "pickup"], modes=modes),
                hammer=dict(mass_kg=m_h, height_m=1.0e-3, velocity_m_per_s=v0),
                contact=dict(stiffness_n_per_m=d["k"], damping_n_s_per_m=d["c"], zeta=zeta, t_c=t_c),
                pickups=[dict(point="pickup", quantity="velocity", gain=1.0)])


# ----------------------------------------------------------------------------------------------
# checks
# ----------------------------------------------------------------------------------------------

TOP_KEYS = {"version", "name", "description", "duration_s", "object", "hammer", "contact", "pickup"}
OBJ_KEYS = {"name", "kind", "points", "mode"}
MODE_KEYS = {"freq_hz", "t60_s", "weights"}
HAMMER_KEYS = {"mass_kg", "height_m", "velocity_m_per_s", "gravity_m_per_s2"}
CONTACT_KEYS = {"object", "point", "stiffness_n_per_m", "damping_n_s_per_m", "switching"}
PICKUP_KEYS = {"object", "point", "quantity", "gain"}


def check_file(path):
    errs = []
    with open(path, "rb") as fh:
        sc = tomllib.load(fh)
    stem = os.path.splitext(os.path.basename(path))[0]

    def need(cond, msg):
        if not cond:
            errs.append(msg)

    need(set(sc) <= TOP_KEYS, f"unknown top-level keys {set(sc) - TOP_KEYS}")
    need(sc.get("version") == 1, "version must be 1")
    need(sc.get("name") == stem, "name must equal the file stem")
    need(isinstance(sc.get("description"), str) and sc["description"], "description missing")
    need(isinstance(sc.get("duration_s"), float) and sc["duration_s"] > 0, "duration_s must be a float > 0")
    objs = sc.get("object", [])
    need(len(objs) == 1, "exactly one object expected")
    ob = objs[0]
    need(set(ob) <= OBJ_KEYS, f"unknown object keys {set(ob) - OBJ_KEYS}")
    need(ob.get("kind") == "modal", "kind must be modal")
    pts = ob.get("points", [])
    need(pts[:2] == ["contact", "pickup"], "points must start with contact, pickup")
    for i, m in enumerate(ob.get("mode", [])):
        need(set(m) <= MODE_KEYS, f"mode[{i}] unknown keys")
        f, t, w = m.get("freq_hz"), m.get("t60_s"), m.get("weights")
        need(isinstance(f, float) and 0 < f < 20000, f"mode[{i}].freq_hz out of range: {f}")
        need(isinstance(t, float) and t > 0, f"mode[{i}].t60_s must be > 0: {t}")
        need(isinstance(w, list) and len(w) == len(pts) and all(isinstance(x, float) and math.isfinite(x) for x in w),
             f"mode[{i}].weights must be {len(pts)} finite floats")
    hm = sc.get("hammer", {})
    need(set(hm) <= HAMMER_KEYS, "unknown hammer keys")
    need(hm.get("mass_kg", 0) > 0, "hammer mass must be > 0")
    need(0.0005 <= hm.get("height_m", 0) <= 0.002, "hammer height out of range")
    need(-3.0 <= hm.get("velocity_m_per_s", 0) <= -0.5, "hammer velocity must be -3..-0.5 m/s")
    need(hm.get("gravity_m_per_s2", 0.0) == 0.0, "gravity must be 0")
    ct = sc.get("contact", {})
    need(set(ct) <= CONTACT_KEYS, "unknown contact keys")
    need(ct.get("object") == ob.get("name") and ct.get("point") == "contact", "contact must name object/contact")
    k, c = ct.get("stiffness_n_per_m", 0), ct.get("damping_n_s_per_m", -1)
    need(k > 0 and c >= 0, "contact k > 0, c >= 0")
    pks = sc.get("pickup", [])
    need(1 <= len(pks) <= 2, "one or two pickups")
    for p in pks:
        need(set(p) <= PICKUP_KEYS, "unknown pickup keys")
        need(p.get("object") == ob.get("name") and p.get("point") in pts and p.get("point") != "contact",
             "pickup must name the object and a pickup point")
        need(p.get("quantity") in ("velocity", "displacement"), "pickup quantity")
    return sc, errs


def report(sc, sim):
    ob = sc["object"][0]
    modes = ob["mode"]
    fr = [m["freq_hz"] for m in modes]
    t6 = [m["t60_s"] for m in modes]
    m_h = sc["hammer"]["mass_kg"]
    k, c = sc["contact"]["stiffness_n_per_m"], sc["contact"]["damping_n_s_per_m"]
    w1 = modes[0]["weights"][0]
    M1 = 1 / w1 ** 2
    m_eff = m_h * M1 / (m_h + M1)
    zeta = c / (2 * math.sqrt(k * m_eff))
    t_est = math.pi / (math.sqrt(k / m_eff) * math.sqrt(1 - zeta ** 2))
    Mmin = min(1 / m["weights"][0] ** 2 for m in modes if m["weights"][0] != 0)
    lines = [
        f"{sc['name']}: {len(modes)} modes, {min(fr):.1f} .. {max(fr):.1f} Hz, T60 {max(t6):.3g} .. {min(t6):.3g} s",
        f"  contact: k = {k:.4g} N/m, c = {c:.4g} N s/m, zeta = {zeta:.3f}, est. t_c = {t_est*1e3:.3f} ms"
        f" (m_eff = {m_eff:.4g} kg); hammer/mode-1 mass ratio m_h/M1 = {m_h/M1:.3g}"
        f" (M1 = {M1:.4g} kg; lightest mode at contact {Mmin:.4g} kg, ratio {m_h/Mmin:.3g})",
    ]
    if sim is not None:
        ct = sim["contacts"]
        first = (ct[0][1] - ct[0][0]) * 1e3 if ct else float("nan")
        lines.append(
            f"  simulated impact (all modes): first contact {first:.3f} ms, {len(ct)} contact(s) in 0.1 s,"
            f" hammer rebound {sim['vh_after']:+.3f} m/s, pickup peak x gain = "
            + ", ".join(f"{pk*p['gain']:.3f}" for pk, p in zip(sim["peaks"], sc["pickup"])))
    return "\n".join(lines)


def to_parsed_like(sc):
    """In-memory scene in the parsed-TOML layout (for simulating before writing)."""
    return {
        "object": [dict(name=sc["object"]["name"], points=sc["object"]["points"],
                        mode=[dict(freq_hz=m["freq_hz"], t60_s=m["t60_s"], weights=m["weights"])
                              for m in sc["object"]["modes"]])],
        "hammer": dict(sc["hammer"], gravity_m_per_s2=0.0),
        "contact": dict(point="contact", stiffness_n_per_m=sc["contact"]["stiffness_n_per_m"],
                        damping_n_s_per_m=sc["contact"]["damping_n_s_per_m"]),
        "pickup": [dict(point=p["point"], quantity=p["quantity"]) for p in sc["pickups"]],
    }


def sig2(x):
    e = math.floor(math.log10(x))
    return round(x / 10 ** (e - 1)) * 10 ** (e - 1)


BUILDERS = [marimba, steel_plate, bell, wood_block, glockenspiel]


def main():
    check_only = "--check" in sys.argv
    names = []
    if not check_only:
        for build in BUILDERS:
            sc = build()
            sim = simulate(to_parsed_like(sc))
            for p, pk in zip(sc["pickups"], sim["peaks"]):
                p["gain"] = sig2(TARGET_PEAK / pk)
            sc["header"] += [
                "",
                "Pickups: velocity (what radiates); gain = 0.5 / simulated peak pickup velocity, so the",
                "  rendered peak is about 0.5 (see the check output of gen_presets.py).",
            ]
            path = write_scene(sc)
            names.append(path)
    else:
        names = [os.path.join(OUT_DIR, b().get("name") + ".toml") for b in BUILDERS]
    ok = True
    for path in names:
        sc, errs = check_file(path)
        sim = simulate(sc)
        print(f"{os.path.basename(path)}: parses with tomllib, {'OK' if not errs else 'ERRORS'}")
        for e in errs:
            print("  ERROR:", e)
            ok = False
        print(report(sc, sim))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
