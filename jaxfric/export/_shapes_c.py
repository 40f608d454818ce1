"""C translations of the presliding shapes (`jaxfric._shapes`, `jaxfric._normalized_shape`):
``jf_shape(xi, &kappa)`` returns ``Pi(xi)`` and its derivative ``kappa`` exactly as
`AbstractShape.pi_kappa_gamma` computes them (negative ``xi`` clipped to 0, ``Pi`` clipped
to 1 from above, ``kappa = 0`` where it is clipped or beyond ``l1``)."""

import math

from .._normalized_shape import _SMALL, NormalizedPaperShape
from .._shapes import PaperShape, PowerShape
from ._parts import const, derived, ExportError, Part


_WRAPPER = """\
/* Pi(xi) (dimensionless) and *kappa = dPi/dxi (N/m) of the presliding shape, xi in m/N. */
static double jf_shape(double xi, double *kappa)
{
    double u, p, dp;
    if (!(xi >= 0.0)) xi = 0.0;
    if (!(xi < JF_L1)) { *kappa = 0.0; return 1.0; }
    u = xi / JF_L1;
    p = jf_profile(u, &dp);
    if (p < 1.0) { *kappa = dp / JF_L1; return p; }
    *kappa = 0.0;
    return 1.0;
}
"""


def _power(shape: PowerShape) -> Part:
    return Part(
        consts=[const(shape, "l1", "JF_L1", "shape"), const(shape, "n", "JF_N", "shape")],
        helpers="""\
/* PowerShape: Pi = 1 - (1 - u)^n on u = xi/l1 in [0, 1); *dp = dPi/du. */
static double jf_profile(double u, double *dp)
{
    double b = 1.0 - u, y;
    if (!(b > 0.0)) { *dp = 0.0; return 1.0; }
    y = pow(b, JF_N);
    *dp = JF_N * y / b;
    return 1.0 - y;
}
""",
    )


def _paper(shape: PaperShape, Fs: float) -> Part:
    a, b, c = (float(getattr(shape, k)) for k in ("a", "b", "c"))
    alpha, beta, l1 = (float(getattr(shape, k)) for k in ("alpha", "beta", "l1"))
    big_x = 2.0 * Fs * l1
    bb = beta**alpha if beta > 0 else 0.0
    amp = -a * math.exp(b * bb)
    top = amp * math.expm1(b * ((big_x + beta) ** alpha - bb)) - c * big_x**4
    if top == 0.0:
        raise ExportError("PaperShape: the saw-tooth curve is 0 at X = 2*Fs*l1; Pi undefined")
    consts = [const(shape, k, f"JF_SHAPE_{k.upper()}", "shape") for k in ("a", "b", "c")]
    consts += [const(shape, "alpha", "JF_ALPHA", "shape"), const(shape, "beta", "JF_BETA", "shape"),
               const(shape, "l1", "JF_L1", "shape"),
               derived("JF_X", big_x, "X = 2*Fs*l1 [m]"),
               derived("JF_BB", bb, "beta^alpha [m^alpha]"),
               derived("JF_AMP", amp, "-a*exp(b*beta^alpha) [N]"),
               derived("JF_FX", top, "F(X), the saw-tooth curve at X [N]")]
    return Part(consts=consts, helpers="""\
/* PaperShape: Pi = F(X*u)/F(X), F(x) = K - a*exp(b*(x+beta)^alpha) - c*x^4, F(0) = 0. */
static double jf_profile(double u, double *dp)
{
    double x = JF_X * u, q = x + JF_BETA, pw = 0.0, dpw = 0.0, em1, f, df;
    if (q > 0.0) { pw = pow(q, JF_ALPHA); dpw = JF_ALPHA * pw / q; }
    em1 = expm1(JF_SHAPE_B * (pw - JF_BB));
    f = JF_AMP * em1 - JF_SHAPE_C * x * x * x * x;
    df = JF_AMP * (1.0 + em1) * JF_SHAPE_B * dpw - 4.0 * JF_SHAPE_C * x * x * x;
    *dp = JF_X * df / JF_FX;
    return f / JF_FX;
}
""")


def _normalized(shape: NormalizedPaperShape) -> Part:
    alpha, br, k = (float(getattr(shape, n)) for n in ("alpha", "beta_rel", "curvature"))
    lo = br**alpha if br > 0 else 0.0
    span = (1.0 + br) ** alpha - lo
    small = abs(k) < _SMALL
    consts = [const(shape, n, f"JF_{n.upper()}", "shape")
              for n in ("l1", "alpha", "beta_rel", "curvature", "quartic")]
    consts += [derived("JF_LO", lo, "beta_rel^alpha [-]"),
               derived("JF_SPAN", span, "(1+beta_rel)^alpha - beta_rel^alpha [-]"),
               derived("JF_EXPK", 0.0 if small else math.expm1(-k), "expm1(-curvature) [-]")]
    if small:
        ratio = """\
    /* |curvature| < 1e-6: the series of expm1(-k*w)/expm1(-k) */
    r = w * (1.0 + 0.5 * JF_CURVATURE * (1.0 - w));
    dr = dw * (1.0 + 0.5 * JF_CURVATURE * (1.0 - w)) - w * 0.5 * JF_CURVATURE * dw;"""
    else:
        ratio = """\
    r = expm1(-JF_CURVATURE * w) / JF_EXPK;
    dr = -JF_CURVATURE * exp(-JF_CURVATURE * w) * dw / JF_EXPK;"""
    helpers = f"""\
/* NormalizedPaperShape: Pi = (ratio(w) - quartic*u^4)/(1 - quartic),
   w = ((u+beta_rel)^alpha - lo)/span, ratio = expm1(-curvature*w)/expm1(-curvature). */
static double jf_profile(double u, double *dp)
{{
    double q = u + JF_BETA_REL, pw = 0.0, dpw = 0.0, w = 0.0, dw = 0.0, r, dr;
    if (q > 0.0) {{ pw = pow(q, JF_ALPHA); dpw = JF_ALPHA * pw / q; }}
    if (JF_SPAN != 0.0) {{ w = (pw - JF_LO) / JF_SPAN; dw = dpw / JF_SPAN; }}
{ratio}
    *dp = (dr - 4.0 * JF_QUARTIC * u * u * u) / (1.0 - JF_QUARTIC);
    return (r - JF_QUARTIC * u * u * u * u) / (1.0 - JF_QUARTIC);
}}
"""
    return Part(consts=consts, helpers=helpers)


def shape_part(shape, Fs: float) -> Part:
    """The `Part` defining ``jf_shape`` for `shape` (static level `Fs`, N)."""
    if type(shape) is PowerShape:
        part = _power(shape)
    elif type(shape) is PaperShape:
        part = _paper(shape, Fs)
    elif type(shape) is NormalizedPaperShape:
        part = _normalized(shape)
    else:
        raise ExportError(f"the presliding shape {type(shape).__name__} has no C translation "
                          "(supported: PaperShape, NormalizedPaperShape, PowerShape)")
    part.helpers += _WRAPPER
    return part
