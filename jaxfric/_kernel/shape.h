// The shape functions of the two-state forward kernel (forward.cc): `safe_div` and `spow`
// (`jaxfric._numerics`), the shape's per-trajectory constants (`Shape`, `make_shape`), its
// profile, Pi and kappa (`pi_kappa`, as `AbstractShape.pi_kappa_gamma`) for any T (double,
// or dual numbers for the Jacobian), and `shape_values`, Pi and gamma of a block of branch
// samples: one at a time for any T, and for T = double a branchless loop that vectorises
// (vmath.h). Shapes: 0 `PaperShape` (a, b, c, alpha, beta), 1 `PowerShape` (n),
// 2 `NormalizedPaperShape` (alpha, beta_rel, curvature, quartic), read from the packed
// parameters p[7..] after Fs = p[0] and l1 = p[6].

#ifndef JAXFRIC_KERNEL_SHAPE_H_
#define JAXFRIC_KERNEL_SHAPE_H_

#include <cmath>
#include <cstdint>

#include "dual.h"
#include "vmath.h"

namespace jaxfric {

using std::exp;
using std::expm1;
using std::fabs;
using std::log;

// `jaxfric._numerics.safe_div`: num / den, and 0 (with no derivative) where den == 0.
template <typename A, typename B>
inline auto safe_div(const A& num, const B& den) -> decltype(num / den) {
  using R = decltype(num / den);
  return value(den) == 0.0 ? R(0.0) : num / den;
}

// `jaxfric._numerics.safe_pow`: exp(p*log(x)) for x > 0, else 0.
template <typename A, typename B>
inline auto spow(const A& x, const B& p) -> decltype(p * x) {
  using R = decltype(p * x);
  return value(x) > 0.0 ? R(exp(p * log(x))) : R(0.0);
}

template <typename T>
struct Shape {
  int kind;
  T l1, Fs;
  T a, b, c, alpha, beta, bb, ea, big_x, f_big_x;  // paper
  T n;                                             // power
  T br, lo, span, k, q;                            // normalized
  bool small;
};

template <typename T>
T saw(const Shape<T>& sh, const T& z) {
  return -sh.ea * expm1(sh.b * (spow(z + sh.beta, sh.alpha) - sh.bb)) - sh.c * (z * z * z * z);
}

template <typename T>
Shape<T> make_shape(int kind, const T* p) {
  Shape<T> sh{};
  sh.kind = kind;
  sh.Fs = p[0];
  sh.l1 = p[6];
  if (kind == 0) {
    sh.a = p[7];
    sh.b = p[8];
    sh.c = p[9];
    sh.alpha = p[10];
    sh.beta = p[11];
    sh.bb = spow(sh.beta, sh.alpha);
    sh.ea = sh.a * exp(sh.b * sh.bb);
    sh.big_x = 2.0 * sh.Fs * sh.l1;
    sh.f_big_x = saw(sh, sh.big_x);
  } else if (kind == 1) {
    sh.n = p[7];
  } else {
    sh.alpha = p[7];
    sh.br = p[8];
    sh.k = p[9];
    sh.q = p[10];
    sh.lo = spow(sh.br, sh.alpha);
    sh.span = spow(1.0 + sh.br, sh.alpha) - sh.lo;
    sh.small = fabs(value(sh.k)) < 1e-6;  // `_normalized_shape._SMALL`
  }
  return sh;
}

// The profile P(u) and dP/du on u = xi/l1 in [0, 1) (`AbstractShape._profile`).
template <typename T>
void profile(const Shape<T>& sh, const T& u, T& P, T& dP) {
  if (sh.kind == 0) {
    const T z = sh.big_x * u, zb = z + sh.beta;
    const T pw = spow(zb, sh.alpha);
    const T e = sh.b * (pw - sh.bb);
    const T z3 = z * z * z;
    const T num = -sh.ea * expm1(e) - sh.c * (z3 * z);
    const T dpw = value(zb) > 0.0 ? T(sh.alpha * pw / zb) : T(0.0);
    const T dnum = -sh.ea * exp(e) * sh.b * dpw - 4.0 * sh.c * z3;
    P = safe_div(num, sh.f_big_x);
    dP = safe_div(dnum * sh.big_x, sh.f_big_x);
  } else if (sh.kind == 1) {
    const T w = 1.0 - u;
    const T y = spow(w, sh.n);
    P = 1.0 - y;
    dP = value(w) > 0.0 ? T(sh.n * y / w) : T(0.0);
  } else {
    const T ub = u + sh.br;
    const T pw = spow(ub, sh.alpha);
    const T w = safe_div(pw - sh.lo, sh.span);
    const T dw =
        (value(ub) > 0.0 && value(sh.span) != 0.0) ? T(sh.alpha * pw / ub / sh.span) : T(0.0);
    T R, dR;
    if (sh.small) {
      R = w * (1.0 + 0.5 * sh.k * (1.0 - w));
      dR = 1.0 + 0.5 * sh.k * (1.0 - 2.0 * w);
    } else {
      const T den = expm1(-sh.k);
      R = expm1(-sh.k * w) / den;
      dR = -sh.k * exp(-sh.k * w) / den;
    }
    const T u3 = u * u * u;
    P = (R - sh.q * (u3 * u)) / (1.0 - sh.q);
    dP = (dR * dw - 4.0 * sh.q * u3) / (1.0 - sh.q);
  }
}

// Pi and kappa at xi (clipped to >= 0 first; `AbstractShape.pi_kappa_gamma`); xi is
// replaced by the clipped value.
template <typename T>
void pi_kappa(const Shape<T>& sh, T& xi, T& p, T& k) {
  if (!(value(xi) >= 0.0)) xi = T(0.0);
  if (!(value(xi) < value(sh.l1))) {
    p = T(1.0);
    k = T(0.0);
    return;
  }
  T P, dP;
  profile(sh, T(safe_div(xi, sh.l1)), P, dP);
  if (value(P) < 1.0) {
    p = P;
    k = value(sh.l1) != 0.0 ? T(dP / sh.l1) : T(0.0);
  } else {
    p = T(1.0);
    k = T(0.0);
  }
}

template <typename T>
T pi_only(const Shape<T>& sh, T xi) {
  T p, k;
  pi_kappa(sh, xi, p, k);
  return p;
}

// Pi and gamma = Pi - xi*kappa of the branch samples xi[0..m) (`pi_kappa`, clipping
// included), for any T: one sample at a time.
template <typename T>
void shape_values(const Shape<T>& sh, const T* xi, int64_t m, T* pi, T* gamma) {
  for (int64_t i = 0; i < m; ++i) {
    T x = xi[i], p, k;
    pi_kappa(sh, x, p, k);
    pi[i] = p;
    gamma[i] = p - x * k;
  }
}

// The same for T = double, written without branches: every operation runs on every sample
// and selects pick the results (no && of conditions, no conditional call), as in
// `stribeck_block`, with vmath.h's exp, log and expm1, so that the loops vectorise: the
// shape is most of a presliding sample's work. exp(e) is taken as expm1(e) + 1 (one
// rounding apart). Agrees with `pi_kappa` to a few ulp (tests/core/test_forward_kernel.py).
// The clipping: P < 1 else (1, 0); xi >= l1 (or l1 NaN) gives (1, 0).
JAXFRIC_SIMD_CLONES
inline void shape_values(const Shape<double>& sh, const double* xs, int64_t m, double* pi,
                  double* gamma) {
  using jaxfric::vexp;
  using jaxfric::vexpm1;
  using jaxfric::vlog;
  const double l1 = sh.l1, l1s = l1 != 0.0 ? l1 : 1.0, l1on = l1 != 0.0 ? 1.0 : 0.0;
  // u = safe_div(xi, l1), and the results from P, dP/du
#define JAXFRIC_CLIP_AND_STORE(P, dP)                   \
  const double k_in = ((dP) / l1s) * l1on;              \
  const double p1 = (P) < 1.0 ? (P) : 1.0;              \
  const double k1 = (P) < 1.0 ? k_in : 0.0;             \
  const double p = xi < l1 ? p1 : 1.0;                  \
  const double k = xi < l1 ? k1 : 0.0;                  \
  pi[i] = p;                                            \
  gamma[i] = p - xi * k;
  if (sh.kind == 0) {
    const double big_x = sh.big_x, beta = sh.beta, alpha = sh.alpha, b = sh.b, bb = sh.bb;
    const double ea = sh.ea, c = sh.c, fbx = sh.f_big_x;
    const double fbxs = fbx != 0.0 ? fbx : 1.0, fbxon = fbx != 0.0 ? 1.0 : 0.0;
    for (int64_t i = 0; i < m; ++i) {
      const double x0 = xs[i];
      const double xi = x0 >= 0.0 ? x0 : 0.0;  // NaN -> 0, as `pi_kappa`
      const double u = (xi / l1s) * l1on;
      const double z = big_x * u, zb = z + beta;
      const bool pos = zb > 0.0;
      const double zbs = pos ? zb : 1.0;
      const double pw_all = vexp(alpha * vlog(zbs));
      const double pw = pos ? pw_all : 0.0;
      const double e = b * (pw - bb);
      const double em1 = vexpm1(e);
      const double z3 = z * z * z;
      const double num = -ea * em1 - c * (z3 * z);
      const double dpw_all = alpha * pw / zbs;
      const double dpw = pos ? dpw_all : 0.0;
      const double dnum = -ea * (em1 + 1.0) * b * dpw - 4.0 * c * z3;
      const double P = (num / fbxs) * fbxon;
      const double dP = (dnum * big_x / fbxs) * fbxon;
      JAXFRIC_CLIP_AND_STORE(P, dP)
    }
  } else if (sh.kind == 1) {
    const double nn = sh.n;
    for (int64_t i = 0; i < m; ++i) {
      const double x0 = xs[i];
      const double xi = x0 >= 0.0 ? x0 : 0.0;
      const double u = (xi / l1s) * l1on;
      const double w = 1.0 - u;
      const bool pos = w > 0.0;
      const double ws = pos ? w : 1.0;
      const double y_all = vexp(nn * vlog(ws));
      const double y = pos ? y_all : 0.0;
      const double P = 1.0 - y;
      const double dP_all = nn * y / ws;
      const double dP = pos ? dP_all : 0.0;
      JAXFRIC_CLIP_AND_STORE(P, dP)
    }
  } else {
    const double alpha = sh.alpha, br = sh.br, lo = sh.lo, span = sh.span, kk = sh.k;
    const double q = sh.q, spans = span != 0.0 ? span : 1.0, spanon = span != 0.0 ? 1.0 : 0.0;
    const double den = sh.small ? 1.0 : std::expm1(-kk);
    const double small = sh.small ? 1.0 : 0.0;  // a double: selects on it vectorise
    for (int64_t i = 0; i < m; ++i) {
      const double x0 = xs[i];
      const double xi = x0 >= 0.0 ? x0 : 0.0;
      const double u = (xi / l1s) * l1on;
      const double ub = u + br;
      const bool pos = ub > 0.0;
      const double ubs = pos ? ub : 1.0;
      const double pw_all = vexp(alpha * vlog(ubs));
      const double pw = pos ? pw_all : 0.0;
      const double w = ((pw - lo) / spans) * spanon;
      const double dw_all = (alpha * pw / ubs / spans) * spanon;
      const double dw = pos ? dw_all : 0.0;
      const double em1 = vexpm1(-kk * w);
      const double R_series = w * (1.0 + 0.5 * kk * (1.0 - w));
      const double dR_series = 1.0 + 0.5 * kk * (1.0 - 2.0 * w);
      const double R_exp = em1 / den, dR_exp = -kk * (em1 + 1.0) / den;
      const double R = small > 0.0 ? R_series : R_exp;
      const double dR = small > 0.0 ? dR_series : dR_exp;
      const double u3 = u * u * u;
      const double P = (R - q * (u3 * u)) / (1.0 - q);
      const double dP = (dR * dw - 4.0 * q * u3) / (1.0 - q);
      JAXFRIC_CLIP_AND_STORE(P, dP)
    }
  }
#undef JAXFRIC_CLIP_AND_STORE
}

}  // namespace jaxfric

#endif  // JAXFRIC_KERNEL_SHAPE_H_
