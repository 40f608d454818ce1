"""C translations of the friction models' per-sample ``step`` (jaxfric/_models/*.py): each
returns a `Part` whose step statements set ``f`` (N) from ``t, x, v, dt`` and the state.
The state's ``x_prev`` (the previous sample's position) is updated by the caller after the
model and the effects. Every branch follows the JAX code line by line; the comments name
the JAX function each block translates."""

from .._models.gms import GMS
from .._models.lugre import LuGre
from .._models.tustin import Tustin
from .._models.two_state import TwoState
from ._parts import c_double, const, ExportError, Part, unit_of
from ._shapes_c import shape_part


_STRIBECK = """\
/* |s(v)| (N): Fc + (Fs - Fc)*exp(-(|v|/Vs)^delta), Fs at v = 0 (Stribeck.magnitude). */
static double jf_smag(double v)
{
    double u = fabs(v) / JF_VS;
    return JF_FC + (JF_FS - JF_FC) * exp(-(u > 0.0 ? pow(u, JF_DELTA) : 0.0));
}

/* s(v) = sgn(v)*|s(v)| (N), 0 at v = 0 (Stribeck.__call__). */
static double jf_s(double v) { return jf_sign(v) * jf_smag(v); }

/* v, or the step's dx/dt where sign(v) disagrees with the step (motion.consistent_velocity). */
static inline double jf_consistent(double v, double dx, double dt)
{
    if (!(v * dx < 0.0)) return v;
    return dt > 0.0 ? dx / dt : 0.0;
}
"""


def _stribeck(model) -> Part:
    st = model.stribeck
    return Part(consts=[const(st, n, f"JF_{n.upper()}", "stribeck")
                        for n in ("Fs", "Fc", "Vs", "delta")], helpers=_STRIBECK)


_TWO_STATE_HELPERS = """\
#define JF_K JAXFRIC_STACK_SIZE

/* Slot of logical entry lev (0 <= base, lev < JF_K): (base + lev) % JF_K without a division. */
static int jf_slot(const jaxfric_state *s, int lev)
{
    int i = s->base + lev;
    return i >= JF_K ? i - JF_K : i;
}

static int jf_top(const jaxfric_state *s) { return jf_slot(s, s->depth - 1); }

/* Rule 1 at reversal point x_r with rest value s_r: push with wiping-out and overflow
   (TwoState._push). */
static void jf_push(jaxfric_state *s, double x_r, double s_r)
{
    int top = jf_top(s), base, depth, over, wipe, slot;
    double den = s_r - s->ms[top], kappa;
    double h_r = s->mh[top] + jf_shape(jf_div(x_r - s->mx[top], den), &kappa) * den;
    double theta = jf_div(fabs(x_r - s->mx[top]), fabs(den));
    wipe = theta > JF_L1;
    base = wipe ? top : s->base;
    depth = (wipe ? 1 : s->depth) + 1;
    over = depth > JF_K;
    if (over) { base = base + 1 == JF_K ? 0 : base + 1; depth = JF_K; }
    if (over || (wipe && s->depth > 1)) s->zero_bottom = 0;
    s->overflow += over;
    s->base = base;
    s->depth = depth;
    slot = jf_top(s);
    s->mx[slot] = x_r;
    s->mh[slot] = h_r;
    s->ms[slot] = s_r;
    s->mtheta[slot] = theta;
    s->mclosable[slot] = theta <= JF_L1;
}

/* Whether level lev (its slot) is closed by position x with Stribeck value S: closable,
   level 1 only onto the zero state, and xi >= theta (TwoState._close, _top_closes). */
static int jf_closes(const jaxfric_state *s, int lev, double x, double S)
{
    int slot = jf_slot(s, lev);
    return s->mclosable[slot] && (lev >= 2 || s->zero_bottom)
        && jf_div(x - s->mx[slot], S - s->ms[slot]) >= s->mtheta[slot];
}

/* Rules 2 and 3: close every loop x has closed, from the top down (TwoState._close). */
static void jf_close(jaxfric_state *s, double x, double S)
{
    int lev, lowest = -1;
    for (lev = s->depth - 1; lev >= 1; lev -= 2) {
        if (!jf_closes(s, lev, x, S)) break;
        lowest = lev;
    }
    if (lowest >= 1) s->depth = (lowest == 1 ? 0 : lowest - 2) + 1;
}

/* TwoState.step: F = F_h + F_l + sigma2*v. */
static double jf_model(jaxfric_state *s, double x, double v, double dt)
{
    v = jf_consistent(v, x - s->x_prev, dt);
    double d = jf_sign(v), last_d, S, den, xi, p, kappa, gamma, f_h, a;
    int moving = d != 0.0, top;
    int reversal = moving && s->last_d != 0.0 && d != s->last_d;
    last_d = moving ? d : s->last_d;
    S = v != 0.0 ? jf_s(v) : JF_FS * last_d;
    if (reversal) jf_push(s, s->x_prev, JF_FS * s->last_d);
    if (s->depth >= 2 && jf_closes(s, s->depth - 1, x, S)) jf_close(s, x, S);
    top = jf_top(s);
    den = S - s->ms[top];
    xi = jf_div(x - s->mx[top], den);
    p = jf_shape(xi, &kappa);
    gamma = p - (xi >= 0.0 ? xi : 0.0) * kappa;
    f_h = s->mh[top] + p * den;
    /* F_l: exact decay between events, reset at reversals (TwoState._lag_coefficients) */
    a = reversal ? 0.0 : (moving ? exp(-JF_C * jf_div(dt, fabs(S))) : 1.0);
    /* a direction-change step (reversal, first motion) charges nothing: gamma = 0 there */
    s->lag = a * s->lag - ((moving && d != s->last_d) ? 0.0 : gamma * (S - s->s_prev));
    s->last_d = last_d;
    s->s_prev = S;
    return f_h + s->lag + JF_SIGMA2 * v;
}
"""

_TWO_STATE_INIT = """\
    for (i = 0; i < JF_K; ++i) {
        s->mx[i] = 0.0; s->mh[i] = 0.0; s->ms[i] = 0.0; s->mtheta[i] = 0.0;
        s->mclosable[i] = 0;
    }
    s->mx[0] = x0;
    s->base = 0;
    s->depth = 1;
    s->zero_bottom = 1;
    s->overflow = 0;
    s->lag = 0.0;
    s->last_d = 0.0;
    s->s_prev = 0.0;
"""


def _two_state(model: TwoState) -> Part:
    part = _stribeck(model)
    shape = shape_part(model.shape, float(model.stribeck.Fs))
    return Part(
        fields=[
            "/* memory stack (circular buffer; logical entry i in slot (base + i) % size) */",
            "double mx[JAXFRIC_STACK_SIZE]; /* reversal positions [m] */",
            "double mh[JAXFRIC_STACK_SIZE]; /* F_h at the branch starts [N] */",
            "double ms[JAXFRIC_STACK_SIZE]; /* Stribeck rest values at the reversals [N] */",
            "double mtheta[JAXFRIC_STACK_SIZE]; /* presliding extents [m/N] */",
            "int mclosable[JAXFRIC_STACK_SIZE]; /* theta <= l1 */",
            "int base, depth, zero_bottom",
            "long overflow; /* entries dropped because the stack was full */",
            "double lag; /* F_l [N] */",
            "double last_d; /* direction of the last motion (-1, 0, 1) */",
            "double s_prev; /* Stribeck value S of the previous sample [N] */",
        ],
        consts=part.consts + shape.consts + [const(model, "sigma2", "JF_SIGMA2", "model"),
                                             const(model, "C", "JF_C", "model")],
        helpers=part.helpers + shape.helpers + _TWO_STATE_HELPERS,
        init=_TWO_STATE_INIT,
    )


_GMS_HELPERS = """\
/* GMS.step (GMS._update for every element): F = sum F_i + sigma2*v. */
static double jf_model(jaxfric_state *s, double x, double v, double dt)
{
    v = jf_consistent(v, x - s->x_prev, dt);
    double d = jf_sign(v), last_d, S, rate, dx = x - s->x_prev, sum = 0.0;
    int moving = d != 0.0, same, i;
    same = moving && d == s->last_d;
    last_d = moving ? d : s->last_d;
    S = v != 0.0 ? jf_s(v) : JF_FS * last_d;
    rate = moving ? JF_C * jf_div(dt, fabs(S)) : 0.0;
    for (i = 0; i < JF_NEL; ++i) {
        double target = JF_NU[i] * S, f_stick = s->F[i] + JF_KEL[i] * dx;
        double cap = JF_NU[i] * (JF_FS > JF_FC ? JF_FS : JF_FC);
        double lim0 = JF_NU[i] * fabs(s->S_prev), lim1 = JF_NU[i] * fabs(S);
        int slipping = s->slipping[i] && same;
        int starts = moving && d * f_stick > lim1;
        if (starts) { /* the limit met at fraction theta of the sample, slipping after */
            double gap0 = lim0 - d * s->F[i], gap1 = lim1 - d * f_stick, theta = 0.0;
            if (gap0 > 0.0) theta = fmin(fmax(jf_div(gap0, gap0 - gap1), 0.0), 1.0);
            f_stick = target + (d * (lim0 + theta * (lim1 - lim0)) - target)
                               * exp(-(1.0 - theta) * rate);
        }
        else if (f_stick < -cap) f_stick = -cap;
        else if (f_stick > cap) f_stick = cap;
        s->F[i] = slipping ? target + (s->F[i] - target) * exp(-rate) : f_stick;
        s->slipping[i] = slipping || starts;
        sum += s->F[i];
    }
    s->last_d = last_d;
    s->S_prev = S;
    return sum + JF_SIGMA2 * v;
}
"""


def _gms(model: GMS) -> Part:
    part = _stribeck(model)
    n = int(model.nu.shape[0])
    arrays = (
        f"#define JF_NEL {n}\n"
        f"/* model.nu [{unit_of(model, 'nu')}]: element weights */\n"
        f"static const double JF_NU[JF_NEL] = {{{', '.join(c_double(v) for v in model.nu)}}};\n"
        f"/* model.k [{unit_of(model, 'k')}]: element stiffnesses */\n"
        f"static const double JF_KEL[JF_NEL] = {{{', '.join(c_double(v) for v in model.k)}}};\n"
    )
    return Part(
        fields=[f"double F[{n}]; /* element forces [N] */",
                f"int slipping[{n}]; /* element slip flags */",
                "double last_d; /* direction of the last motion (-1, 0, 1) */",
                "double S_prev; /* the previous sample's limit curve S [N] */"],
        consts=part.consts + [const(model, "sigma2", "JF_SIGMA2", "model"),
                              const(model, "C", "JF_C", "model")],
        helpers=arrays + part.helpers + _GMS_HELPERS,
        init="    for (i = 0; i < JF_NEL; ++i) { s->F[i] = 0.0; s->slipping[i] = 0; }\n"
             "    s->last_d = 0.0;\n    s->S_prev = 0.0;\n",
    )


_LUGRE_HELPERS = """\
/* LuGre.step: z updated over the step's displacement dx, 1/g by the trapezoid rule between
   the previous sample's speed (s->v_prev, set by the caller) and this one's (no step for
   dt <= 0);
   F = sigma0*z + sigma1*dz/dt + sigma2*v. */
static double jf_model(jaxfric_state *s, double x, double v, double dt)
{
    double dx = dt > 0.0 ? x - s->x_prev : 0.0, g = jf_smag(v);
    double k = 0.5 * (1.0 / g + 1.0 / jf_smag(s->v_prev));
    double a = exp(-JF_SIGMA0 * fabs(dx) * k), zdot;
    s->z = a * s->z + (1.0 - a) * jf_sign(dx) / (JF_SIGMA0 * k);
    zdot = v - JF_SIGMA0 * fabs(v) * s->z / g;
    return JF_SIGMA0 * s->z + JF_SIGMA1 * zdot + JF_SIGMA2 * v;
}
"""


def _lugre(model: LuGre) -> Part:
    part = _stribeck(model)
    return Part(
        fields=["double z; /* bristle deflection [m] */"],
        consts=part.consts + [const(model, n, f"JF_{n.upper()}", "model")
                              for n in ("sigma0", "sigma1", "sigma2")],
        helpers=part.helpers + _LUGRE_HELPERS,
        init="    s->z = 0.0;\n",
    )


_TUSTIN_HELPERS = """\
/* Tustin.step: F = s(v) + sigma2*v, no state. */
static double jf_model(jaxfric_state *s, double x, double v, double dt)
{
    (void)s; (void)x; (void)dt;
    return jf_s(v) + JF_SIGMA2 * v;
}
"""


def _tustin(model: Tustin) -> Part:
    part = _stribeck(model)
    return Part(consts=part.consts + [const(model, "sigma2", "JF_SIGMA2", "model")],
                helpers=part.helpers + _TUSTIN_HELPERS)


_TRANSLATORS = {TwoState: _two_state, GMS: _gms, LuGre: _lugre, Tustin: _tustin}


def model_part(model) -> Part:
    """The `Part` defining ``jf_model(s, x, v, dt)`` for a friction model without effects."""
    translate = _TRANSLATORS.get(type(model))
    if translate is None:
        raise ExportError(f"the model {type(model).__name__} has no C translation "
                          "(supported: TwoState, GMS, LuGre, Tustin)")
    return translate(model)


def stack_size(model) -> int:
    """The memory size the export reserves (`TwoState.stack_size`; 1 for other models)."""
    return int(model.stack_size) if isinstance(model, TwoState) else 1
