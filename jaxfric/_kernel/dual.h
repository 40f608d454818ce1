// Forward-mode dual numbers for the kernels of jaxfric/_kernel (forward.cc).
//
// Dual<N> carries a value and its derivatives with respect to N inputs; the arithmetic and
// the functions the two-state model needs (exp, log, expm1, fabs) propagate them by the
// chain rule. The same templated code then runs on double (the forces) and on Dual<N> (the
// forces and their Jacobian). `value` reads the value of either, for the model's discrete
// decisions, which are taken on values only.

#ifndef JAXFRIC_KERNEL_DUAL_H_
#define JAXFRIC_KERNEL_DUAL_H_

#include <cmath>

namespace jaxfric {

template <int N>
struct Dual {
  double v = 0.0;
  double d[N] = {};
  Dual() = default;
  Dual(double value) : v(value) {}  // NOLINT: a constant (no derivatives)
  static Dual input(double value, int k) {
    Dual r(value);
    r.d[k] = 1.0;
    return r;
  }
};

inline double value(double x) { return x; }
template <int N>
inline double value(const Dual<N>& x) { return x.v; }

// r = a*x + b*y (derivatives only; the value is set by the caller).
template <int N>
inline void axpby(Dual<N>& r, double a, const Dual<N>& x, double b, const Dual<N>& y) {
  for (int k = 0; k < N; ++k) r.d[k] = a * x.d[k] + b * y.d[k];
}
template <int N>
inline Dual<N> scaled(double value, double a, const Dual<N>& x) {
  Dual<N> r(value);
  for (int k = 0; k < N; ++k) r.d[k] = a * x.d[k];
  return r;
}

template <int N>
inline Dual<N> operator+(const Dual<N>& x, const Dual<N>& y) {
  Dual<N> r(x.v + y.v);
  axpby(r, 1.0, x, 1.0, y);
  return r;
}
template <int N>
inline Dual<N> operator-(const Dual<N>& x, const Dual<N>& y) {
  Dual<N> r(x.v - y.v);
  axpby(r, 1.0, x, -1.0, y);
  return r;
}
template <int N>
inline Dual<N> operator*(const Dual<N>& x, const Dual<N>& y) {
  Dual<N> r(x.v * y.v);
  axpby(r, y.v, x, x.v, y);
  return r;
}
template <int N>
inline Dual<N> operator/(const Dual<N>& x, const Dual<N>& y) {
  const double q = x.v / y.v;
  Dual<N> r(q);
  axpby(r, 1.0 / y.v, x, -q / y.v, y);
  return r;
}
template <int N>
inline Dual<N> operator-(const Dual<N>& x) {
  return scaled(-x.v, -1.0, x);
}
template <int N>
inline Dual<N> operator+(const Dual<N>& x, double y) {
  Dual<N> r = x;
  r.v += y;
  return r;
}
template <int N>
inline Dual<N> operator+(double y, const Dual<N>& x) {
  return x + y;
}
template <int N>
inline Dual<N> operator-(const Dual<N>& x, double y) {
  Dual<N> r = x;
  r.v -= y;
  return r;
}
template <int N>
inline Dual<N> operator-(double y, const Dual<N>& x) {
  return scaled(y - x.v, -1.0, x);
}
template <int N>
inline Dual<N> operator*(const Dual<N>& x, double y) {
  return scaled(x.v * y, y, x);
}
template <int N>
inline Dual<N> operator*(double y, const Dual<N>& x) {
  return scaled(y * x.v, y, x);
}
template <int N>
inline Dual<N> operator/(const Dual<N>& x, double y) {
  return scaled(x.v / y, 1.0 / y, x);
}
template <int N>
inline Dual<N> operator/(double y, const Dual<N>& x) {
  const double q = y / x.v;
  return scaled(q, -q / x.v, x);
}

template <int N>
inline Dual<N> exp(const Dual<N>& x) {
  const double e = std::exp(x.v);
  return scaled(e, e, x);
}
template <int N>
inline Dual<N> expm1(const Dual<N>& x) {
  return scaled(std::expm1(x.v), std::exp(x.v), x);
}
template <int N>
inline Dual<N> log(const Dual<N>& x) {
  return scaled(std::log(x.v), 1.0 / x.v, x);
}
template <int N>
inline Dual<N> fabs(const Dual<N>& x) {
  return x.v < 0.0 ? -x : x;
}

}  // namespace jaxfric

#endif  // JAXFRIC_KERNEL_DUAL_H_
