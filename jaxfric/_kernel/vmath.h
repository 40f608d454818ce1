// Vectorisable exp and log for float64, and the Stribeck pre-pass of forward.cc.
//
// libm's exp and log are function calls the compiler cannot vectorise, and in the two-state
// forward pass they are most of the time: every moving sample needs s(v) =
// Fc + (Fs - Fc)*exp(-exp(delta*log(|v|/Vs))) and the lag's decay exp(-C*dt/|s|). Both
// depend on the sample alone, so `stribeck_block` computes them for a block of samples in a
// loop without branches, which the compiler turns into SIMD code (with -fno-trapping-math),
// before the sequential loop reads them; forward.cc's `shape_values` does the same for the
// shape. With GCC 12 or later on x86-64 Linux these loops (`JAXFRIC_SIMD_CLONES`) also get
// clones for x86-64-v4 (AVX-512: 8 samples per instruction) and x86-64-v3 (AVX2: 4), the
// best the CPU has picked at run time, in which a*b + c is one fused instruction
// (fp-contract=fast: the polynomials' chains are half as long; results move by an ulp or
// so). Everything else is compiled without contraction. `vexpm1` is `vexp` with the
// polynomial of exp(r) - 1 (no cancellation near 0).
//
// `vexp`: k = round(x/ln2), r = x - k*ln2 (two-part ln2), exp(r) by its Taylor polynomial
// of degree 13 (|r| <= ln2/2: truncation < 5e-18 relative), times 2^k built in the exponent
// bits; x is clamped to [-708, 709] (normal results). `vlog` (x > 0, normal): x = 2^e * m
// with m in [sqrt(1/2), sqrt(2)), log m = 2*atanh(s), s = (m-1)/(m+1), |s| <= 0.1716, by its
// series to s^21 (truncation < 1e-17). Both agree with libm to a few ulp (checked in
// tests/core/test_forward_kernel.py through the forces, which agree with the JAX path to
// 1e-12 relative).

#ifndef JAXFRIC_KERNEL_VMATH_H_
#define JAXFRIC_KERNEL_VMATH_H_

#include <cstdint>
#include <cstring>

#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__) && \
    __GNUC__ >= 12
#define JAXFRIC_SIMD_CLONES \
  __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default"), \
                 optimize("fp-contract=fast")))
#elif defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__)
// (GCC before 12: the level names may be unknown; an AVX2 clone without FMA.)
#define JAXFRIC_SIMD_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define JAXFRIC_SIMD_CLONES
#endif

namespace jaxfric {

inline double bits_to_double(uint64_t b) {
  double d;
  std::memcpy(&d, &b, sizeof d);
  return d;
}
inline uint64_t double_to_bits(double d) {
  uint64_t b;
  std::memcpy(&b, &d, sizeof b);
  return b;
}

inline double vexp(double x) {
  x = x < -708.0 ? -708.0 : x;
  x = x > 709.0 ? 709.0 : x;
  const double shift = 6755399441055744.0;  // 1.5 * 2^52: adding it rounds to an integer
  const double kd_shifted = x * 1.4426950408889634 + shift;
  const uint64_t ki = double_to_bits(kd_shifted);
  const double kd = kd_shifted - shift;
  const double r = (x - kd * 6.93147180369123816490e-01) - kd * 1.90821492927058770002e-10;
  double p = 1.0 / 6227020800.0;  // 1/13!
  p = p * r + 1.0 / 479001600.0;
  p = p * r + 1.0 / 39916800.0;
  p = p * r + 1.0 / 3628800.0;
  p = p * r + 1.0 / 362880.0;
  p = p * r + 1.0 / 40320.0;
  p = p * r + 1.0 / 5040.0;
  p = p * r + 1.0 / 720.0;
  p = p * r + 1.0 / 120.0;
  p = p * r + 1.0 / 24.0;
  p = p * r + 1.0 / 6.0;
  p = p * r + 0.5;
  p = p * r + 1.0;
  p = p * r + 1.0;
  // The low bits of ki hold k (two's complement): the exponent field of 2^k.
  return p * bits_to_double((ki + 1023) << 52);
}

inline double vlog(double x) {
  // A subnormal x is scaled into the normal range first (2^54), its exponent corrected.
  const bool tiny = x < 2.2250738585072014e-308;
  x = tiny ? x * 18014398509481984.0 : x;
  const uint64_t b = double_to_bits(x);
  // The exponent as a double without an int-to-double conversion.
  double e = bits_to_double((b >> 52) | 0x4330000000000000ULL) - (4503599627370496.0 + 1023.0);
  double m = bits_to_double((b & 0x000FFFFFFFFFFFFFULL) | 0x3FF0000000000000ULL);
  const bool big = m > 1.4142135623730951;
  const double half = 0.5 * m, e1 = e + 1.0;  // computed either way: no branch in the loop
  m = big ? half : m;
  e = big ? e1 : e;
  e = tiny ? e - 54.0 : e;
  const double s = (m - 1.0) / (m + 1.0), s2 = s * s;
  double q = 1.0 / 21.0;
  q = q * s2 + 1.0 / 19.0;
  q = q * s2 + 1.0 / 17.0;
  q = q * s2 + 1.0 / 15.0;
  q = q * s2 + 1.0 / 13.0;
  q = q * s2 + 1.0 / 11.0;
  q = q * s2 + 1.0 / 9.0;
  q = q * s2 + 1.0 / 7.0;
  q = q * s2 + 1.0 / 5.0;
  q = q * s2 + 1.0 / 3.0;
  q = q * s2 + 1.0;
  return e * 6.93147180369123816490e-01 + (2.0 * s * q + e * 1.90821492927058770002e-10);
}

// expm1(x): exp(r) - 1 for the reduced r by its own polynomial (no cancellation near 0),
// then 2^k * expm1(r) + (2^k - 1).
inline double vexpm1(double x) {
  x = x < -708.0 ? -708.0 : x;
  x = x > 709.0 ? 709.0 : x;
  const double shift = 6755399441055744.0;
  const double kd_shifted = x * 1.4426950408889634 + shift;
  const uint64_t ki = double_to_bits(kd_shifted);
  const double kd = kd_shifted - shift;
  const double r = (x - kd * 6.93147180369123816490e-01) - kd * 1.90821492927058770002e-10;
  double q = 1.0 / 87178291200.0;  // 1/14!; q = sum_{j>=2} r^(j-2)/j!
  q = q * r + 1.0 / 6227020800.0;
  q = q * r + 1.0 / 479001600.0;
  q = q * r + 1.0 / 39916800.0;
  q = q * r + 1.0 / 3628800.0;
  q = q * r + 1.0 / 362880.0;
  q = q * r + 1.0 / 40320.0;
  q = q * r + 1.0 / 5040.0;
  q = q * r + 1.0 / 720.0;
  q = q * r + 1.0 / 120.0;
  q = q * r + 1.0 / 24.0;
  q = q * r + 1.0 / 6.0;
  q = q * r + 0.5;
  const double em = r + (r * r) * q;
  const double two_k = bits_to_double((ki + 1023) << 52);
  return two_k * em + (two_k - 1.0);
}

// The velocity of sample j > 0 (`jaxfric.motion.consistent_velocity` of the given one, or
// `backward_velocity` when there is none), written without branches.
inline double motion_velocity(double dt, double dx, double v_in, bool has_v) {
  const double back = dt > 0.0 ? dx / (dt > 0.0 ? dt : 1.0) : 0.0;
  const double v = has_v ? v_in : back;
  return v * dx < 0.0 ? back : v;
}

// For samples j0 .. j0+m-1 of one trajectory: vel[i] (`motion_velocity`; v_0 is the given
// one, or 0), mag[i] = |s(v_j)| (the Stribeck magnitude, used where v_j != 0) and decay[i] =
// exp(-C*dt_j/mag[i]) (dt_0 = 0), as `Stribeck.magnitude` and
// `TwoState._lag_coefficients` (p: Fs, Fc, Vs, delta, C).
JAXFRIC_SIMD_CLONES
inline void stribeck_block(const double* t, const double* x, const double* v, bool has_v,
                           int64_t j0, int64_t m, const double* p, double* vel, double* mag,
                           double* decay) {
  const double Fs = p[0], Fc = p[1], Vs = p[2], delta = p[3], C = p[4];
  const double dfs = Fs - Fc;
  // Every operation runs on every sample and selects pick the results (safe_div, safe_pow):
  // no branch, so the loops vectorise.
  const double vs_safe = Vs != 0.0 ? Vs : 1.0, vs_on = Vs != 0.0 ? 1.0 : 0.0;
  const double* tp = t + j0;
  const double* xp = x + j0;
  const double* vp = v + j0;
  const int64_t first = j0 == 0 ? 1 : 0;
  if (first == 1 && m > 0) vel[0] = has_v ? v[0] : 0.0;
  for (int64_t i = first; i < m; ++i) {
    vel[i] = motion_velocity(tp[i] - tp[i - 1], xp[i] - xp[i - 1], vp[i], has_v);
  }
  for (int64_t i = 0; i < m; ++i) {
    const double av = vel[i] < 0.0 ? -vel[i] : vel[i];
    const double u = (av / vs_safe) * vs_on;
    const double lu = vlog(u > 0.0 ? u : 1.0);
    const double e = vexp(delta * lu);
    const double pw = u > 0.0 ? e : 0.0;
    mag[i] = Fc + dfs * vexp(-pw);
  }
  // The decay over dt_j = t_j - t_{j-1} (0 at j = 0), with the magnitude just computed.
  if (first == 1 && m > 0) decay[0] = 1.0;
  for (int64_t i = first; i < m; ++i) {
    const double mg = mag[i];
    const double q = (tp[i] - tp[i - 1]) / (mg != 0.0 ? mg : 1.0);
    decay[i] = vexp(-C * (mg != 0.0 ? q : 0.0));
  }
}

}  // namespace jaxfric

#endif  // JAXFRIC_KERNEL_VMATH_H_
