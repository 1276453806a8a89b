"""Template of the per-model kernel: pasted by sim.compiled after binding the model's functions.

Not imported directly.  The generated module defines, before this text, the model's
numba functions as globals ``rhs, guards, on_event, observe, bounded`` (``rhs`` and ``guards`` inlined where the
step calls them; ``rhs_once`` and ``guards_once``, the same functions called once per cycle or switch), the
counts ``N_BOUNDED`` and ``N_GUARDS``, the tuple ``GUARD_STATES``, the index ``IW`` of the excitation work in the
state and the tuple ``HIDDEN_SWITCHES`` of the parameters (mass ratios) that switch on a mode in the hidden states
(see the model interface in sim.integrator).
Binding them as globals, rather than passing them as arguments, is what lets numba cache the compiled kernel on disk
and release the GIL.
"""
# ruff: noqa: F821  (rhs, guards, rhs_once, guards_once, on_event, observe, bounded, N_BOUNDED, N_GUARDS,
# GUARD_STATES, IW, HIDDEN_SWITCHES: bound by sim.compiled)
import numpy as np

from sim.integrator import *  # noqa: F401,F403  constants and helpers
from sim.integrator import _crossed, _dense, _dense_some, track_maxima, window_switch
from sim.kernel import N_ACC, _rel_close, settled_period

# after the star import, which re-exports sim.jit's lazy njit: this module is imported only to compile the kernel,
# so its own functions are numba's dispatchers directly
from numba import njit  # noqa: E402

# ERRORS (sim.integrator, star-imported above): every kernel function divides the IEEE way

# Hook of a hybrid exact propagator (sim/exact/rimd.py, sim/exact/indenter.py; bound by sim.compiled in place of these
# three): where ``exact_ok`` says so (the RIMD: in free flight; the indenter: while its seal friction is constant),
# ``exact_free`` advances the state exactly to where the numerical steps must take over (a contact onset, a velocity
# reversal) or to the cycle end, switches and their bookkeeping done.  False here: numba prunes the branch.  A hybrid
# may also replace ``step_hint``, the step after an accepted numerical one (the indenter: across its friction's tanh).
HYBRID = False


@njit(cache=True, nogil=True, error_model=ERRORS)
def exact_ok(t, y, z, ph, p, gk):
    """Placeholder of the hook (never called while HYBRID is False): whether the exact propagator takes over here."""
    return False


@njit(cache=True, nogil=True, error_model=ERRORS)
def exact_free(p, y, z, ph, t, t_end, period, s, atol, record, acc, bmin, bmax, cyc, counters, gk):
    """Placeholder of the hook (never called while HYBRID is False); returns (time reached, phase)."""
    return t_end, ph


@njit(cache=True, nogil=True, error_model=ERRORS)
def step_hint(t, y, z, ph, p, dy, h, h_done, en_done):
    """Optional part of the hook (a hybrid that knows what limits its numerical stretches replaces it, see
    sim/exact/indenter.py): the next step [s] after an accepted one of length h_done [s] with error norm en_done,
    given the step controller's proposal h and the derivative dy at the state y reached.  Here: h."""
    return h


@njit(cache=True, nogil=True, error_model=ERRORS)
def _locate(t, h, y, z, ph, p, r1, r2, r3, r4, r5, yd, gbuf, i, a, b, fa, fb, ev_tol):
    """Illinois (modified regula falsi) root of guard i on the dense output, bisection every
    third iteration.  Returns the right bracket (on the crossed side) within ev_tol seconds.  Only the states
    the guards read are interpolated (yd's other entries are stale)."""
    side = 0
    it = 0
    while (b - a) * h > ev_tol and it < 200:
        it += 1
        if it % 3 == 0 or fb == fa:
            c = 0.5 * (a + b)
        else:
            c = (a * fb - b * fa) / (fb - fa)
            if not (c > a and c < b):
                c = 0.5 * (a + b)
        _dense_some(r1, r2, r3, r4, r5, c, yd, GUARD_STATES)
        guards(t + c * h, yd, z, ph, p, gbuf)
        fc = gbuf[i]
        if _crossed(fa, fc):
            b = c
            fb = fc
            if side == -1:
                fa *= 0.5
            side = -1
        else:
            a = c
            fa = fc
            if side == 1:
                fb *= 0.5
            side = 1
    return b


@njit(cache=True, nogil=True, error_model=ERRORS)
def _peak_on(t, h, z, ph, p, r1, r2, r3, r4, r5, yd, obs, dyd, a, b, which):
    """Max over θ in [a, b] of the contact force (which = OBS_FORCE) or of the deceleration
    (which = OBS_ACCEL: −accel) on the step's interpolant: Brent's method (parabolic steps with a golden
    section fallback, Numerical Recipes §10.3) to 1e-5 of [a, b].  The first pass only evaluates the start
    point: one call site of the inlined observation (each site is a copy of the model's equations to compile)."""
    cg = 0.3819660112501051
    tol1 = 1e-5 * (b - a)
    tol2 = 2.0 * tol1
    x = a + cg * (b - a)
    w = x
    v = x
    u = x
    fx = 0.0
    fw = 0.0
    fv = 0.0
    d = 0.0
    e = 0.0
    for it in range(61):
        if it > 0:
            m = 0.5 * (a + b)
            if abs(x - m) <= tol2 - 0.5 * (b - a):
                break
            golden = True
            if abs(e) > tol1:
                r = (x - w) * (fx - fv)
                q = (x - v) * (fx - fw)
                pp = (x - v) * q - (x - w) * r
                q = 2.0 * (q - r)
                if q > 0.0:
                    pp = -pp
                q = abs(q)
                etemp = e
                e = d
                if abs(pp) < abs(0.5 * q * etemp) and pp > q * (a - x) and pp < q * (b - x):
                    d = pp / q
                    u = x + d
                    if u - a < tol2 or b - u < tol2:
                        d = tol1 if m >= x else -tol1
                    golden = False
            if golden:
                e = (a - x) if x >= m else (b - x)
                d = cg * e
            if abs(d) >= tol1:
                u = x + d
            else:
                u = x + (tol1 if d > 0.0 else -tol1)
        fu = -_objective(t, h, z, ph, p, r1, r2, r3, r4, r5, yd, obs, dyd, u, which)
        if it == 0:
            fx = fu
            fw = fu
            fv = fu
        elif fu <= fx:
            if u >= x:
                a = x
            else:
                b = x
            v = w
            fv = fw
            w = x
            fw = fx
            x = u
            fx = fu
        else:
            if u < x:
                a = u
            else:
                b = u
            if fu <= fw or w == x:
                v = w
                fv = fw
                w = u
                fw = fu
            elif fu <= fv or v == x or v == w:
                v = u
                fv = fu
    return -fx


@njit(cache=True, nogil=True, error_model=ERRORS, inline="always")
def _objective(t, h, z, ph, p, r1, r2, r3, r4, r5, yd, obs, dyd, th, which):
    _dense(r1, r2, r3, r4, r5, th, yd)
    observe(t + th * h, yd, z, ph, p, obs, dyd)
    return obs[OBS_FORCE] if which == OBS_FORCE else -obs[OBS_ACCEL]


@njit(cache=True, nogil=True, error_model=ERRORS, inline="always")
def _may_reach(v0, vm, v1, run):
    """Whether one accepted (sub-)step θ ∈ [0, th_ev], given its samples of the force or the deceleration at the
    start v0, middle vm and end v1, can reach ``run`` (the running window maximum): the sample maximum or, when
    the samples bend down, the vertex of their parabola plus a margin.  Scalars only, inlined: most steps end
    here, with no call (a call costs numba a reference count per array argument).

    Only such a step is refined (``_step_max``), on the step's interpolant over the part that holds the maximum
    (``_peak_on``): best in the middle -> [0, th_ev]; best at the start -> [0, th_ev/2] if the value rises just
    after the start, else nothing (the start is it); best at the end -> [th_ev/2, th_ev]
    if the value falls just before the end, else nothing (the quantity is still rising: its maximum lies in
    the next step, which finds it as its start's half, or at a switch, where the end value is it); equal
    samples at θ = 0, 1/4, 1/2, 3/4 and 1 of th_ev -> nothing (a plateau: its value is the maximum).
    The peak is therefore found to the interpolant's accuracy, never extrapolated across a step boundary.
    """
    best = max(v0, vm, v1)
    est = best
    c = 0.5 * (v0 + v1) - vm              # parabola through (0, v0), (1, vm), (2, v1) in u = 2θ/th_ev
    if c < 0.0:
        b = 0.5 * (v1 - v0)
        u = 1.0 - b / (2.0 * c)
        if u > 0.0 and u < 2.0:
            est = max(est, vm - b * b / (4.0 * c))
        # the parabola misses the higher-order terms of a coarse step (on indenter-metal at rtol 1e-8 by
        # 5e-6 of the peak, 2e-3 of |c|); a margin of |c| / 2 refines every step near a bent-down maximum
        est -= 0.5 * c
    return est >= run


@njit(cache=True, nogil=True, error_model=ERRORS)
def _step_max(t, h, z, ph, p, r1, r2, r3, r4, r5, yd, obs, dyd, th_ev, v0, vm, v1, which):
    """The step's maximum where ``_may_reach`` (its docstring) says it can reach the running maximum.  The probes
    and the search are each written once (one call site each of the inlined observation)."""
    best = max(v0, vm, v1)
    hm = 0.5 * th_ev
    lo = 0.0               # the part [lo, hi] of the step searched when the probes allow it
    hi = th_ev
    n_probe = 0
    ref = v0               # a probe above ref (plateau: different from ref) calls for the search
    th_a = 0.0
    if v0 == vm and vm == v1:
        # three equal samples: a plateau, e.g. the drill's force Pr through phase III.  Brent's method would
        # spend ~25 observations finding its constant maximum on every step; two more samples confirm it
        n_probe = 2
        th_a = 0.5 * hm
    elif vm >= v0 and vm >= v1:
        n_probe = 0
    elif v0 >= v1:
        n_probe = 1
        th_a = th_ev * 1e-4
        hi = hm
    else:
        n_probe = 1
        th_a = th_ev * (1.0 - 1e-4)
        ref = v1
        lo = hm
    search = n_probe == 0
    for k in range(n_probe):
        f = _objective(t, h, z, ph, p, r1, r2, r3, r4, r5, yd, obs, dyd, th_a if k == 0 else 1.5 * hm, which)
        if n_probe == 2:
            if f != ref:          # not a plateau after all
                search = True
                break
        else:
            search = f > ref      # rising just after the start, or falling just before the end
    if not search:
        return best           # a plateau, or the maximum at the start or the end (the step before or after has it)
    return max(best, _peak_on(t, h, z, ph, p, r1, r2, r3, r4, r5, yd, obs, dyd, lo, hi, which))


@njit(cache=True, nogil=True, error_model=ERRORS)
def integrate_cycles(p, y, z, ph_arr, t0, period, n_cycles, s,
                     atol, record, strobe, bmin, bmax,
                     acc, hist_t, hist_y, hist_obs, hist_ph, hist_dt, counters, wk, gk):
    """Integrate ``n_cycles`` whole forcing cycles from ``t0`` (y, z, ph_arr edited in place).

    strobe[c] receives the bounded coordinates at the start of cycle c, bmin/bmax
    their per-cycle extremes.  When ``record`` is true, window statistics are
    accumulated into ``acc``:
        acc[0] max contact force, acc[1] sum of per-contact maxima, acc[2] number of
        completed contacts, acc[3] contact onsets, acc[4] max deceleration (m/s²),
        acc[5] current contact's running max, acc[6] 1 if any time was spent in contact,
        acc[7] -1 while the contact open at the window start lasts, then its max (-2: none)
    and, when hist_dt > 0, uniform samples are written to hist_* (index counters[2]).
    counters: [steps, events, hist_index, status, reason].
    wk (WK_ROWS, ny) and gk (GK_ROWS, max(N_GUARDS, N_OBS, N_BOUNDED)) are scratch space (``make_workspace``).
    Returns the end time.
    """
    ny = y.shape[0]
    # the RMS error counts the hidden mode's two states (the last two) only while a mode that uses them is on: off,
    # they stay 0 and the norm is the base model's, bit for bit
    hidden = False
    for i in HIDDEN_SWITCHES:
        if p[i] != 0.0:
            hidden = True
    n_err = ny if hidden else ny - 2
    ng = N_GUARDS
    rtol = s[S_RTOL]
    # views of the run's workspace (allocated once per run_point, not per call)
    k1 = wk[0]; k2 = wk[1]; k3 = wk[2]; k4 = wk[3]; k5 = wk[4]; k6 = wk[5]; k7 = wk[6]
    ytmp = wk[7]; y1 = wk[8]
    r1 = wk[9]; r2 = wk[10]; r3 = wk[11]; r4 = wk[12]; r5 = wk[13]
    yd = wk[14]; dyd = wk[15]
    g0 = gk[0, :ng]; g1 = gk[1, :ng]; gm = gk[2, :ng]     # the model's N_GUARDS guards, no more
    obs = gk[3, :N_OBS]
    nbd = strobe.shape[1]
    bvec = gk[4, :nbd]
    hmax = s[S_MAX_STEP_FRAC] * period
    ev_tol = s[S_EVENT_TOL] * period
    max_steps = int(s[S_MAX_STEPS_PER_CYCLE])
    max_total = int(s[S_MAX_STEPS])
    ph = ph_arr[0]
    t = t0
    h = 1e-3 * period
    # step-end force / deceleration of the previous accepted step (-inf: unknown, after a switch)
    f_prev = -np.inf
    d_prev = -np.inf

    for cyc in range(n_cycles):
        t_end = t0 + (cyc + 1) * period
        bounded(t, y, z, ph, p, bvec)
        for j in range(nbd):
            strobe[cyc, j] = bvec[j]
            bmin[cyc, j] = bvec[j]
            bmax[cyc, j] = bvec[j]
        rhs_once(t, y, z, ph, p, k1)
        guards_once(t, y, z, ph, p, g0)
        steps_this_cycle = 0
        fresh = True   # the current step starts at a cycle start or a switch
        while t < t_end:
            if t_end - t <= 1e-12 * period:
                t = t_end
                break
            steps_this_cycle += 1
            if steps_this_cycle > max_steps or counters[0] > max_total:
                counters[3] = STATUS_FAILED
                counters[4] = REASON_TOO_MANY_STEPS if steps_this_cycle > max_steps else REASON_WORK_LIMIT
                ph_arr[0] = ph
                return t
            if HYBRID:
                if exact_ok(t, y, z, ph, p, gk):
                    t, ph = exact_free(p, y, z, ph, t, t_end, period, s, atol, record, acc, bmin, bmax, cyc,
                                       counters, gk)
                    if t_end - t > 1e-12 * period:   # the numerical steps take over from here (at the cycle end:
                        rhs_once(t, y, z, ph, p, k1)    # the next cycle's start does this)
                        guards_once(t, y, z, ph, p, g0)
                    f_prev = -np.inf
                    d_prev = -np.inf
                    fresh = True
                    continue
            h = min(h, hmax, t_end - t)
            if h < 1e-14 * period:
                counters[3] = STATUS_FAILED
                counters[4] = REASON_STEP_UNDERFLOW
                ph_arr[0] = ph
                return t
            # ---- one DOPRI5 step
            for i in range(ny):
                ytmp[i] = y[i] + h * A21 * k1[i]
            rhs(t + C2 * h, ytmp, z, ph, p, k2)
            for i in range(ny):
                ytmp[i] = y[i] + h * (A31 * k1[i] + A32 * k2[i])
            rhs(t + C3 * h, ytmp, z, ph, p, k3)
            for i in range(ny):
                ytmp[i] = y[i] + h * (A41 * k1[i] + A42 * k2[i] + A43 * k3[i])
            rhs(t + C4 * h, ytmp, z, ph, p, k4)
            for i in range(ny):
                ytmp[i] = y[i] + h * (A51 * k1[i] + A52 * k2[i] + A53 * k3[i] + A54 * k4[i])
            rhs(t + C5 * h, ytmp, z, ph, p, k5)
            for i in range(ny):
                ytmp[i] = y[i] + h * (A61 * k1[i] + A62 * k2[i] + A63 * k3[i] + A64 * k4[i] + A65 * k5[i])
            rhs(t + h, ytmp, z, ph, p, k6)
            for i in range(ny):
                y1[i] = y[i] + h * (A71 * k1[i] + A73 * k3[i] + A74 * k4[i] + A75 * k5[i] + A76 * k6[i])
            rhs(t + h, y1, z, ph, p, k7)
            # RMS of the error estimate scaled by atol + rtol max(|y|, |y1|) (written out: an inlined helper taking
            # arrays costs numba a reference-count increment and decrement per array on every step)
            sq = 0.0
            for i in range(ny):
                e = h * (E1 * k1[i] + E3 * k3[i] + E4 * k4[i] + E5 * k5[i] + E6 * k6[i] + E7 * k7[i])
                e = e / (atol[i] + rtol * max(abs(y[i]), abs(y1[i])))
                sq += e * e
            en = np.sqrt(sq / n_err)
            if not np.isfinite(en):
                h *= 0.1
                if h < 1e-14 * period:
                    counters[3] = STATUS_FAILED
                    counters[4] = REASON_NONFINITE
                    ph_arr[0] = ph
                    return t
                continue
            if en > 1.0:
                h *= max(0.2, 0.9 * en ** -0.2)
                continue
            counters[0] += 1
            # ---- dense output coefficients
            for i in range(ny):
                r1[i] = y[i]
                ydiff = y1[i] - y[i]
                r2[i] = ydiff
                bspl = h * k1[i] - ydiff
                r3[i] = bspl
                r4[i] = ydiff - h * k7[i] - bspl
                r5[i] = h * (D1 * k1[i] + D3 * k3[i] + D4 * k4[i] + D5 * k5[i] + D6 * k6[i] + D7 * k7[i])
            # ---- event detection: end point and interior points
            guards(t + h, y1, z, ph, p, g1)
            th_lo = 0.0
            th_hi = 2.0
            k_ev = -1
            # earliest bracket: scan interior points in order
            prev_th = 0.0
            for q in range(4):
                if q < 3:
                    th = 0.25 * (q + 1)
                    _dense_some(r1, r2, r3, r4, r5, th, yd, GUARD_STATES)   # the guards' states only
                    guards(t + th * h, yd, z, ph, p, gm)
                else:
                    th = 1.0
                    for i in range(ng):
                        gm[i] = g1[i]
                for i in range(ng):
                    if k_ev < 0 and _crossed(g0[i], gm[i]):
                        k_ev = i
                        th_lo = prev_th
                        th_hi = th
                if k_ev >= 0:
                    break
                # advance the lower reference: g0 becomes guard values at this sample
                for i in range(ng):
                    g0[i] = gm[i]
                prev_th = th
            if k_ev >= 0:
                # refine every guard that crossed in [th_lo, th_hi]; take the earliest root
                _dense_some(r1, r2, r3, r4, r5, th_lo, yd, GUARD_STATES)
                guards_once(t + th_lo * h, yd, z, ph, p, g0)
                _dense_some(r1, r2, r3, r4, r5, th_hi, yd, GUARD_STATES)
                guards_once(t + th_hi * h, yd, z, ph, p, gm)
                th_ev = th_hi
                best_k = -1
                for i in range(ng):
                    if _crossed(g0[i], gm[i]):
                        b = _locate(t, h, y, z, ph, p, r1, r2, r3, r4, r5, yd, g1, i,
                                    th_lo, th_hi, g0[i], gm[i], ev_tol)
                        if best_k < 0 or b < th_ev:
                            th_ev = b
                            best_k = i
                k_ev = best_k
            else:
                th_ev = 1.0
            # ---- accepted (possibly truncated) sub-step [t, t + th_ev*h]
            t_new = t + th_ev * h
            if th_ev < 1.0:
                _dense(r1, r2, r3, r4, r5, th_ev, y1)
            # monitoring: the window maxima of the contact force and the deceleration.  Samples at the
            # step's start (the previous end, known unless a switch intervened), middle and end; the step's
            # own maximum is then located on its interpolant (``_step_max``), so no peak is looked for
            # across a step boundary or a switch.
            if record:
                in_c = ph > 0
                if in_c:
                    acc[6] = 1.0
                if fresh or f_prev == -np.inf:
                    observe(t, y, z, ph, p, obs, dyd)
                    f_prev = obs[OBS_FORCE]
                    d_prev = -obs[OBS_ACCEL]
                hm = 0.5 * th_ev
                _dense(r1, r2, r3, r4, r5, hm, yd)
                observe(t + hm * h, yd, z, ph, p, obs, dyd)
                f_mid = obs[OBS_FORCE]
                d_mid = -obs[OBS_ACCEL]
                observe(t_new, y1, z, ph, p, obs, dyd)
                f_end = obs[OBS_FORCE]
                d_end = -obs[OBS_ACCEL]
                bd = max(d_prev, d_mid, d_end)
                if _may_reach(d_prev, d_mid, d_end, acc[4]):
                    bd = _step_max(t, h, z, ph, p, r1, r2, r3, r4, r5, yd, obs, dyd, th_ev,
                                   d_prev, d_mid, d_end, OBS_ACCEL)
                if in_c:
                    bf = max(f_prev, f_mid, f_end)
                    if _may_reach(f_prev, f_mid, f_end, acc[5]):
                        bf = _step_max(t, h, z, ph, p, r1, r2, r3, r4, r5, yd, obs, dyd, th_ev,
                                       f_prev, f_mid, f_end, OBS_FORCE)
                    if bf > acc[0]:
                        acc[0] = bf
                    if bf > acc[5]:
                        acc[5] = bf
                if bd > acc[4]:
                    acc[4] = bd
                f_prev = f_end
                d_prev = d_end
                # uniform history samples
                if hist_dt > 0.0:
                    idx = counters[2]
                    while idx < hist_t.shape[0]:
                        ts = hist_t[idx]
                        if ts > t_new + 1e-12 * period:
                            break
                        th = (ts - t) / h
                        if th < 0.0:
                            th = 0.0
                        _dense(r1, r2, r3, r4, r5, th, yd)
                        observe(ts, yd, z, ph, p, obs, dyd)
                        for i in range(ny):
                            hist_y[idx, i] = yd[i]
                        for i in range(N_OBS):
                            hist_obs[idx, i] = obs[i]
                        hist_ph[idx] = ph
                        idx += 1
                    counters[2] = idx
            bounded(t_new, y1, z, ph, p, bvec)
            for j in range(nbd):
                if bvec[j] < bmin[cyc, j]:
                    bmin[cyc, j] = bvec[j]
                if bvec[j] > bmax[cyc, j]:
                    bmax[cyc, j] = bvec[j]
            # ---- commit
            for i in range(ny):
                y[i] = y1[i]
            t = t_new
            if k_ev >= 0:
                counters[1] += 1
                old = ph
                ph = on_event(t, y, z, ph, p, k_ev)
                if record:
                    window_switch(acc, old, ph)
                    # the state just after the switch (force may jump, e.g. the damper at onset)
                    observe(t, y, z, ph, p, obs, dyd)
                    track_maxima(acc, obs, ph > 0)
                rhs_once(t, y, z, ph, p, k1)
                guards_once(t, y, z, ph, p, g0)
                f_prev = -np.inf
                d_prev = -np.inf
                # the step that ended on a switch was accurate; restart with a modest step
                h = max(h * th_ev, 1e-6 * period)
                fresh = True
            else:
                fresh = False
                for i in range(ny):
                    k1[i] = k7[i]
                for i in range(ng):
                    g0[i] = g1[i]
                fac = 0.9 * max(en, 1e-10) ** -0.2
                h_done = h
                h *= min(5.0, max(0.2, fac))
                if HYBRID:
                    h = step_hint(t, y, z, ph, p, k1, h, h_done, en)
            if t_end - t <= 1e-12 * period:
                t = t_end
        t = t_end
    ph_arr[0] = ph
    return t



@njit(cache=True, nogil=True, error_model=ERRORS)
def make_workspace(p, period, s, ny):
    """Scratch arrays of ``integrate_cycles``, allocated once per run (an exact propagator that replaces
    integrate_cycles replaces this too, see sim.compiled)."""
    return np.empty((WK_ROWS, ny)), np.empty((GK_ROWS, max(N_GUARDS, N_OBS, N_BOUNDED)))


@njit(cache=True, nogil=True, error_model=ERRORS)
def _progress(t, y, z, ph, p, obs, dy):
    observe(t, y, z, ph, p, obs, dy)
    return obs[OBS_PROGRESS]


@njit(cache=True, nogil=True, error_model=ERRORS)
def _record_counters(labels, counters):
    """Copy step/event counts into the labels; True (and status failed) if integration failed."""
    labels[L_STEPS] = counters[0]
    labels[L_EVENTS] = counters[1]
    if counters[3] == STATUS_FAILED:
        labels[L_STATUS] = STATUS_FAILED
        labels[L_REASON] = counters[4]
        return True
    return False


@njit(cache=True, nogil=True, error_model=ERRORS)
def run_point(p, y, z, ph_io, period, s, atol, hist_t, hist_y, hist_obs, hist_ph):
    """Simulate one point from the initial state (y, z, ph_io[0]) and return the label vector.

    y, z and ph_io are updated in place to the final state (for continuation sweeps).

    hist_t: sample times *relative to the window start* (empty: no history).  On return
    hist_t holds absolute times.  Labels layout: sim.integrator.L_*.
    """
    labels = np.zeros(N_LABELS)
    counters = np.zeros(5, dtype=np.int64)
    ph_arr = ph_io
    min_tr = int(s[S_MIN_TRANSIENT])
    max_tr = int(s[S_MAX_TRANSIENT])
    n_win = int(s[S_WINDOW])
    runaway_check = s[S_RUNAWAY_CHECK] > 0.0
    if runaway_check:
        max_tr = max(min(max_tr, 40), 12)
    obs = np.empty(N_OBS)
    dy = np.empty(y.shape[0])
    acc_dummy = np.zeros(N_ACC)
    empty_t = np.empty(0)
    empty_2 = np.empty((0, y.shape[0]))
    empty_o = np.empty((0, N_OBS))
    empty_p = np.empty(0, dtype=np.int64)
    strobe = np.zeros((max(max_tr, 1), N_BOUNDED))
    bmin = np.zeros((max(max_tr, 1), N_BOUNDED))
    bmax = np.zeros((max(max_tr, 1), N_BOUNDED))
    prog = np.zeros(max_tr + 1)
    wk, gk = make_workspace(p, period, s, y.shape[0])
    t = 0.0
    prog[0] = _progress(t, y, z, ph_arr[0], p, obs, dy)
    settled = False
    n_tr = 0
    for c in range(max_tr):
        t = integrate_cycles(p, y, z, ph_arr, t, period, 1, s,
                             atol, False, strobe[c:c + 1], bmin[c:c + 1], bmax[c:c + 1], acc_dummy,
                             empty_t, empty_2, empty_o, empty_p, 0.0, counters, wk, gk)
        n_tr = c + 1
        prog[c + 1] = _progress(t, y, z, ph_arr[0], p, obs, dy)
        if counters[3] == STATUS_FAILED:
            break
        if (not runaway_check) and n_tr >= min_tr and settled_period(strobe, bmin, bmax, c, s[S_SETTLE_TOL]) > 0:
            settled = True
            break
    labels[L_TRANSIENT] = n_tr
    if _record_counters(labels, counters):
        return labels
    # ---- runaway: progression increments that grow linearly (constant drift acceleration)
    if n_tr >= 12 and not settled:
        m = n_tr
        d_last = prog[m] - prog[m - 1]
        dd_first = (prog[m - 8] - prog[m - 9]) - (prog[m - 9] - prog[m - 10])
        dd_last = d_last - (prog[m - 1] - prog[m - 2])
        growing = d_last > 0.0 and dd_first > 0.0 and dd_last > 0.0 and dd_last > 0.5 * dd_first
        for k in range(m - 9, m):
            if (prog[k + 1] - prog[k]) <= (prog[k] - prog[k - 1]):
                growing = False
        # A drift at the cap is a runaway only where the model's pre-check says no steady
        # state exists (drill: Fs >= Pr); elsewhere it is a slow transient -> not_settled.
        if runaway_check:
            labels[L_STATUS] = STATUS_RUNAWAY
            labels[L_REASON] = REASON_DRIFT if growing else REASON_PRECHECK
            labels[L_DRIFT_ACC] = dd_last / (period * period)
            return labels
    # ---- recorded window, in two halves (room for the cycles that make a periodic response's window whole periods)
    n1 = n_win // 2
    n2 = n_win - n1
    ws = np.zeros((n_win + MAX_PERIOD, N_BOUNDED))
    wmin = np.zeros((n_win + MAX_PERIOD, N_BOUNDED))
    wmax = np.zeros((n_win + MAX_PERIOD, N_BOUNDED))
    acc1 = np.zeros(N_ACC)
    acc2 = np.zeros(N_ACC)
    t_win = t
    for i in range(hist_t.shape[0]):
        hist_t[i] += t_win
    ny = y.shape[0]
    prog0 = _progress(t, y, z, ph_arr[0], p, obs, dy)
    w0 = y[IW]
    ph_start = ph_arr[0]
    acc1[6] = 1.0 if ph_start > 0 else 0.0
    acc1[7] = -1.0 if ph_start > 0 else -2.0
    t = integrate_cycles(p, y, z, ph_arr, t, period, n1, s,
                         atol, True, ws[0:n1], wmin[0:n1], wmax[0:n1], acc1,
                         hist_t, hist_y, hist_obs, hist_ph, 1.0 if hist_t.shape[0] > 0 else 0.0, counters, wk, gk)
    prog_mid = _progress(t, y, z, ph_arr[0], p, obs, dy)
    w_mid = y[IW]
    if counters[3] != STATUS_FAILED:
        acc2[5] = acc1[5]
        acc2[7] = acc1[7]
        acc2[6] = 1.0 if ph_arr[0] > 0 else 0.0
        t = integrate_cycles(p, y, z, ph_arr, t, period, n2, s,
                             atol, True, ws[n1:n_win], wmin[n1:n_win], wmax[n1:n_win], acc2,
                             hist_t, hist_y, hist_obs, hist_ph, 1.0 if hist_t.shape[0] > 0 else 0.0, counters, wk, gk)
    if _record_counters(labels, counters):
        return labels
    # period over the window; a contact's period that does not divide it: the second half goes on to whole periods
    # (the labels of an ok run are then means over whole periods, as MODELS.md §5 means them; a run without contact
    # keeps its window)
    ranges = np.empty(N_BOUNDED)
    span_ranges(wmin, wmax, 0, n_win - 1, ranges)
    per = periodicity(ws, ranges, s[S_PERIOD_TOL], n_win)
    in_contact = acc1[6] > 0.0 or acc2[6] > 0.0 or max(acc1[0], acc2[0]) > 0.0
    if in_contact and per > 0 and n_win % per != 0:
        extra = per - n_win % per
        t = integrate_cycles(p, y, z, ph_arr, t, period, extra, s,
                             atol, True, ws[n_win:n_win + extra], wmin[n_win:n_win + extra],
                             wmax[n_win:n_win + extra], acc2, hist_t, hist_y, hist_obs, hist_ph,
                             1.0 if hist_t.shape[0] > 0 else 0.0, counters, wk, gk)
        if _record_counters(labels, counters):
            return labels
        n_win += extra
        n2 += extra
    labels[L_WINDOW] = n_win
    prog1 = _progress(t, y, z, ph_arr[0], p, obs, dy)
    w1 = y[IW]
    t_w = n_win * period
    # mean of per-contact maxima over the contacts whose onset lies in the window.  A contact
    # open at the window end is closed with the part of the contact that was open at the
    # window start (acc[7]): the same contact one window later in a steady state.  A contact
    # open across the half boundary continues in acc2 (running max carried over).
    peak = max(acc1[0], acc2[0])
    n_closed = acc1[2] + acc2[2]
    sum_peaks = acc1[1] + acc2[1]
    if ph_arr[0] > 0:
        sum_peaks += max(acc2[5], acc2[7])
        n_closed += 1.0
    onsets = acc1[3] + acc2[3]
    labels[L_ROP] = (prog1 - prog0) / t_w
    labels[L_PEAK_F] = peak
    labels[L_MEAN_PEAK_F] = sum_peaks / n_closed if n_closed > 0 else 0.0
    labels[L_IMPACTS] = onsets / n_win
    labels[L_DECEL] = max(acc1[4], acc2[4]) / G_ACCEL
    labels[L_ENERGY] = (w1 - w0) / n_win
    dprog = prog1 - prog0
    labels[L_SPEC_E] = (w1 - w0) / dprog if dprog > 0.0 else np.inf
    labels[L_PERIOD] = per
    if not in_contact:
        labels[L_STATUS] = STATUS_NO_CONTACT
        labels[L_ROP] = 0.0 if abs(labels[L_ROP]) < 1e-15 else labels[L_ROP]
        return labels
    # ok: periodic (MODELS.md §5 period >= 1) over a window of whole periods.  A transient that settled (``settled``)
    # without a period in the window is judged like one that did not: steady or not by its half-windows
    if per > 0:
        labels[L_STATUS] = STATUS_OK
        return labels
    # non-periodic: aperiodic (chaotic or quasi-periodic, statistically steady) if the two half-windows agree
    tol = s[S_STAT_TOL]
    r1 = (prog_mid - prog0) / (n1 * period)
    r2 = (prog1 - prog_mid) / (n2 * period)
    i1 = acc1[3] / n1
    i2 = acc2[3] / n2
    fscale = max(acc1[0], acc2[0])
    rscale = max(abs(r1), abs(r2))
    steady = (_rel_close(r1, r2, tol, 1e-3 * rscale + 1e-12) and _rel_close(acc1[0], acc2[0], tol, 1e-9 * fscale)
              and _rel_close(i1, i2, tol, 0.0)
              and _rel_close(w_mid - w0, w1 - w_mid, tol, 1e-12))
    if steady:
        labels[L_STATUS] = STATUS_APERIODIC
    else:
        labels[L_STATUS] = STATUS_NOT_SETTLED
        labels[L_REASON] = REASON_LOST_PERIOD if settled else REASON_NOT_PERIODIC
    return labels
