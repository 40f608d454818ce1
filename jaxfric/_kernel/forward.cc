// The two-state model's whole forward pass as an XLA FFI handler for the CPU (jaxfric/_kernel).
//
// One loop per trajectory computes what `TwoState._simulate` computes from a motion
// (t, x[, v]): the velocity and directions (`jaxfric.motion.make_motion`, `consistent`),
// the Stribeck values, the event pass (as events.cc: Rule 1 with wiping-out and overflow,
// the Rules 2-3 cascade), the branch-start force h of every pushed entry, F_h (Eq. 32) with
// the shape's Pi and gamma (shape.h), the friction lag (`TwoState._lag_coefficients`), and
// F = F_h + F_l + sigma2*v. The discrete decisions are the same comparisons as the JAX
// event pass's; the forces agree with the JAX path to rounding (~1e-15 relative: the
// exponentials and logarithms (vmath.h, libm) differ from XLA's in the last bits, and h is
// summed along the stack instead of by prefix sums). A second handler runs the same loop on
// dual numbers (dual.h) and also returns the Jacobians of F and F_h with respect to the
// 12 parameters: the Python side's custom JVP rule (jaxfric/_kernel/forward.py).
//
// Inputs: t, x, v (..., n) float64 (v the given velocity, made consistent with the steps
// as `jaxfric.motion.consistent_velocity`; unused with has_v = 0: the backward difference
// of x); params (..., 12) float64:
//   Fs, Fc, Vs, delta, sigma2, C, l1, q0, q1, q2, q3, q4 with the shape coordinates q:
//   shape 0 (PaperShape): a, b, c, alpha, beta; 1 (PowerShape): n;
//   2 (NormalizedPaperShape): alpha, beta_rel, curvature, quartic.
// Attributes: shape, stack_size K, limit (the static reversal bound; -1 none), has_v, threads.
// Outputs: force, hysteresis, lag, viscous (..., n) float64, depth (..., n) int32 (depth after
// the sample's events), overflow (...) int32 (entries dropped, plus the reversals beyond
// `limit`; then F_h and F_l are NaN, as in the JAX path). Leading dimensions broadcast as in
// events.cc (a batch dimension of 1 repeats).

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <type_traits>
#include <vector>

#include "dual.h"
#include "rows.h"
#include "shape.h"
#include "stack.h"
#include "vmath.h"
#include "xla/ffi/api/ffi.h"

namespace ffi = xla::ffi;

namespace {

using jaxfric::for_rows;
using jaxfric::Push;
using jaxfric::push_slot;
using jaxfric::lead_dims;
using jaxfric::row_offsets;

using jaxfric::Dual;
using jaxfric::make_shape;
using jaxfric::pi_kappa;
using jaxfric::pi_only;
using jaxfric::safe_div;
using jaxfric::Shape;
using jaxfric::shape_values;
using jaxfric::spow;
using jaxfric::value;
using std::exp;
using std::expm1;
using std::fabs;
using std::log;

//: Entries of the packed parameter vector.
constexpr int kParams = 12;
using D = Dual<kParams>;

struct Row {
  const double* t;
  const double* x;
  const double* v;  // the given velocity, or unused (has_v false)
  bool has_v;
  const double* p;
  double* force;
  double* hyst;
  double* lag;
  double* viscous;
  int32_t* depth;
  int32_t* overflow;
  double* jac_hyst;  // (n, kParams) with T = D, else unused
  double* jac_force;
};

inline double sgn(double v) { return v > 0.0 ? 1.0 : (v < 0.0 ? -1.0 : 0.0); }

inline void store(double* out, double* jac, int64_t j, double y) {
  out[j] = y;
  (void)jac;
}
inline void store(double* out, double* jac, int64_t j, const D& y) {
  out[j] = y.v;
  if (jac) std::copy(y.d, y.d + kParams, jac + j * kParams);
}

// `base + level` for base, level in [0, K): the slot of a stack level (a compare, not a %).
inline int32_t slot_of(int32_t i, int32_t K) { return i >= K ? i - K : i; }

// One trajectory; T = double for the forces, T = D for the forces and their Jacobian with
// respect to the packed parameters. A block of samples at a time, in three passes: the
// events (sequential: the stack, and what each sample's branch needs), the shape on the
// block's branch samples (`shape_values`; for T = double vectorised), then the lag
// recurrence and the outputs (sequential). Outputs that are null pointers are not written.
template <typename T>
void run_row(const Row& r, int64_t n, int32_t K, int kind, int64_t limit) {
  T p[kParams];
  for (int k = 0; k < kParams; ++k) {
    if constexpr (std::is_same_v<T, double>) {
      p[k] = r.p[k];
    } else {
      p[k] = T::input(r.p[k], k);
    }
  }
  const T Fs = p[0], Fc = p[1], Vs = p[2], delta = p[3], sigma2 = p[4], C = p[5];
  const double l1 = value(p[6]);
  const T dfs = Fs - Fc;
  const Shape<T> sh = make_shape(kind, p);
  std::vector<double> X(K, 0.0), TH(K, 0.0), SV(K, 0.0);
  std::vector<T> H(K, T(0.0)), S(K, T(0.0));
  std::vector<char> CL(K, 0);
  X[0] = r.x[0];
  int32_t base = 0, depth = 1, ovf = 0;
  bool zero_bottom = true;
  double last_d = 0.0;
  T s_prev(0.0), lag(0.0);
  int64_t reversals = 0;
  // With T = double the Stribeck magnitudes and the lag's decays come from the vectorised
  // pre-pass (vmath.h).
  constexpr bool pre = std::is_same_v<T, double>;
  constexpr int64_t kBlock = pre ? 256 : 16;
  double vel[kBlock], mag[pre ? kBlock : 1], decay[pre ? kBlock : 1];
  T xi_b[kBlock], den_b[kBlock], h_b[kBlock], s_b[kBlock], a_b[kBlock], pi_b[kBlock],
      gamma_b[kBlock];
  bool charge[kBlock];
  int32_t at[pre ? kBlock : 1];  // T = double: the block's samples that need the shape
  double xi_pi[pre ? kBlock : 1], xi_gamma[pre ? kBlock : 1];
  double stribeck[5] = {value(Fs), value(Fc), value(Vs), value(delta), value(C)};
  for (int64_t j0 = 0; j0 < n; j0 += kBlock) {
    const int64_t m = std::min(kBlock, n - j0);
    if constexpr (pre) {
      jaxfric::stribeck_block(r.t, r.x, r.v, r.has_v, j0, m, stribeck, vel, mag, decay);
    }
    // Pass 1: velocity, Stribeck value, events; the branch of every sample.
    int32_t inside = 0;
    for (int64_t i = 0; i < m; ++i) {
      const int64_t j = j0 + i;
      const double xj = r.x[j];
      const double x_prev = j > 0 ? r.x[j - 1] : r.x[0];
      const double dt = j > 0 ? r.t[j] - r.t[j - 1] : 0.0;
      double vj;
      if constexpr (pre) {
        vj = vel[i];
      } else {
        vj = j > 0 ? jaxfric::motion_velocity(dt, xj - x_prev, r.v[j], r.has_v)
                   : (r.has_v ? r.v[0] : 0.0);
        vel[i] = vj;
      }
      const double d = sgn(vj);
      const bool moving = d != 0.0;
      const double prev_last_d = last_d;
      if (moving) last_d = d;
      // `Stribeck.effective`
      T s;
      if (vj != 0.0) {
        if constexpr (pre) {
          s = d * mag[i];
        } else {
          // As `Stribeck.magnitude`: where exp(-u**delta) is exactly 0, so is its
          // derivative (forming it would give inf * 0).
          const T pw = spow(safe_div(fabs(vj), Vs), delta);
          s = value(pw) > 749.9 ? T(d * Fc) : d * (Fc + dfs * exp(-pw));
        }
      } else {
        s = last_d * Fs;
      }
      const double sv = value(s);
      const bool reversal = moving && prev_last_d != 0.0 && d != prev_last_d;
      int32_t top = slot_of(base + depth - 1, K);
      bool event = reversal;
      if (!event) {  // `TwoState._top_closes`
        event = depth >= 2 && CL[top] && (depth >= 3 || zero_bottom) &&
                safe_div(xj - X[top], sv - SV[top]) >= TH[top];
      }
      if (event) {
        if (reversal) {  // `TwoState._push`
          ++reversals;
          const double x_r = x_prev;
          const T s_r = prev_last_d * Fs;
          const T den = s_r - S[top];
          const T h_r = H[top] + pi_only(sh, T(safe_div(x_r - X[top], den))) * den;
          const double theta = safe_div(fabs(x_r - X[top]), fabs(value(den)));
          const bool wipe = theta > l1;
          const Push ps = push_slot(wipe, top, base, depth, K);
          const int32_t slot = ps.slot;
          X[slot] = x_r;
          H[slot] = h_r;
          S[slot] = s_r;
          SV[slot] = value(s_r);
          TH[slot] = theta;
          CL[slot] = theta <= l1;
          if (ps.over || (wipe && depth > 1)) zero_bottom = false;
          ovf += ps.over ? 1 : 0;
          base = ps.base;
          depth = ps.depth;
        }
        // `TwoState._close`
        int32_t lowest = -1;
        for (int32_t level = depth - 1; level >= 1; level -= 2) {
          const int32_t sl = slot_of(base + level, K);
          const bool valid = CL[sl] && (level >= 2 || zero_bottom);
          if (valid && safe_div(xj - X[sl], sv - SV[sl]) >= TH[sl]) {
            lowest = level;
          } else {
            break;
          }
        }
        if (lowest >= 1) depth = (lowest == 1 ? 0 : lowest - 2) + 1;
        top = slot_of(base + depth - 1, K);
      }
      // `TwoState._branch`: xi, and what F_h needs
      const T den = s - S[top];
      const T xi = safe_div(xj - X[top], den);
      if constexpr (pre) {
        // Only a branch sample inside the presliding range, xi (clipped to >= 0) < l1, needs
        // the shape (`pi_kappa`); the others have Pi = gamma = 1. The block's inside samples
        // are gathered for the vectorised `shape_values`.
        const double xc = xi >= 0.0 ? xi : 0.0;
        if (xc < l1) {
          at[inside] = static_cast<int32_t>(i);
          xi_b[inside++] = xc;
        } else {
          pi_b[i] = 1.0;
          gamma_b[i] = 1.0;
        }
      } else {
        xi_b[i] = xi;
      }
      den_b[i] = den;
      h_b[i] = H[top];
      s_b[i] = s;
      // `TwoState._lag_coefficients`
      if (reversal) {
        a_b[i] = T(0.0);
      } else if (moving) {
        if constexpr (pre) {
          a_b[i] = decay[i];
        } else {
          a_b[i] = exp(-C * safe_div(dt, fabs(s)));
        }
      } else {
        a_b[i] = T(1.0);
      }
      // A direction-change step (a reversal or the first motion) charges nothing.
      charge[i] = !(moving && d != prev_last_d);
      if (r.depth) r.depth[j0 + i] = depth;
    }
    // Pass 2: Pi and gamma on the branches.
    if constexpr (pre) {
      shape_values(sh, xi_b, inside, xi_pi, xi_gamma);
      for (int32_t k = 0; k < inside; ++k) {
        pi_b[at[k]] = xi_pi[k];
        gamma_b[at[k]] = xi_gamma[k];
      }
    } else {
      shape_values(sh, xi_b, m, pi_b, gamma_b);
    }
    // Pass 3: F_h (Eq. 32), the lag, the force.
    for (int64_t i = 0; i < m; ++i) {
      const int64_t j = j0 + i;
      const T f_h = h_b[i] + pi_b[i] * den_b[i];
      const T b = charge[i] ? T(-gamma_b[i] * (s_b[i] - s_prev)) : T(0.0);
      lag = a_b[i] * lag + b;
      const T visc = sigma2 * vel[i];
      store(r.force, r.jac_force, j, T(f_h + lag + visc));
      if (r.hyst) {
        store(r.hyst, r.jac_hyst, j, f_h);
        r.lag[j] = value(lag);
        r.viscous[j] = value(visc);
      }
      s_prev = s_b[i];
    }
  }
  if (limit >= 0 && reversals > limit) {  // a bound below the true count: NaN, counted
    const double nan = std::numeric_limits<double>::quiet_NaN();
    std::fill(r.force, r.force + n, nan);
    if (r.hyst) {
      std::fill(r.hyst, r.hyst + n, nan);
      std::fill(r.lag, r.lag + n, nan);
    }
    if constexpr (!std::is_same_v<T, double>) {  // as the JAX path's where(fits, F, nan)
      std::fill(r.jac_force, r.jac_force + n * kParams, 0.0);
      if (r.jac_hyst) std::fill(r.jac_hyst, r.jac_hyst + n * kParams, 0.0);
    }
    ovf += static_cast<int32_t>(reversals - limit);
  }
  *r.overflow = ovf;
}

// Both handlers: the forces, and with T = D also Jacobians (jac_force, jac_hyst).
template <typename T>
ffi::Error Forward(ffi::Buffer<ffi::F64> t, ffi::Buffer<ffi::F64> x, ffi::Buffer<ffi::F64> v,
                   ffi::Buffer<ffi::F64> params, double* force, double* hyst, double* lag,
                   double* viscous, int32_t* depth, ffi::ResultBuffer<ffi::S32>& overflow,
                   double* jac_force, double* jac_hyst, int64_t shape, int64_t stack_size,
                   int64_t limit, int64_t has_v, int64_t threads) {
  auto xd = x.dimensions();
  if (xd.size() < 1) return ffi::Error::InvalidArgument("forward pass: x must have rank >= 1");
  const int64_t n = xd.back();
  const int32_t K = static_cast<int32_t>(stack_size);
  if (n < 1 || K < 1) return ffi::Error::InvalidArgument("forward pass: empty input");
  if (shape < 0 || shape > 2) return ffi::Error::InvalidArgument("forward pass: bad shape");
  if (params.dimensions().back() != kParams) {
    return ffi::Error::InvalidArgument("forward pass: params must have 12 entries");
  }
  if (t.dimensions().back() != n || v.dimensions().back() != n) {
    return ffi::Error::InvalidArgument("forward pass: lengths differ");
  }
  const std::vector<int64_t> out = lead_dims(*overflow, 0);
  std::vector<int64_t> ot, ox, ov, op;
  const bool ok = row_offsets(out, lead_dims(t, 1), ot) && row_offsets(out, lead_dims(x, 1), ox) &&
                  row_offsets(out, lead_dims(v, 1), ov) &&
                  row_offsets(out, lead_dims(params, 1), op);
  if (!ok) return ffi::Error::InvalidArgument("forward pass: batch dimensions do not broadcast");
  const int64_t rows = static_cast<int64_t>(ox.size());
  const int kind = static_cast<int>(shape);
  const int64_t m = jac_force ? n * kParams : 0;
  // The parts (and the hysteresis force's Jacobian) are optional: outputs of 0 elements
  // are not written (null pointers).
  const bool parts = hyst != nullptr;
  if (!parts && jac_hyst != nullptr) {
    return ffi::Error::InvalidArgument("forward pass: jac_hyst needs the parts");
  }
  auto work = [&](int64_t lo, int64_t hi) {
    for (int64_t b = lo; b < hi; ++b) {
      Row r{t.typed_data() + ot[b] * n,
            x.typed_data() + ox[b] * n,
            v.typed_data() + ov[b] * n,
            has_v != 0,
            params.typed_data() + op[b] * kParams,
            force + b * n,
            parts ? hyst + b * n : nullptr,
            parts ? lag + b * n : nullptr,
            parts ? viscous + b * n : nullptr,
            parts ? depth + b * n : nullptr,
            overflow->typed_data() + b,
            jac_hyst ? jac_hyst + b * m : nullptr,
            jac_force ? jac_force + b * m : nullptr};
      run_row<T>(r, n, K, kind, limit);
    }
  };
  // A share of 2^14 samples is about a millisecond of work at tens of ns per sample.
  for_rows(rows, n, threads, 14, work);
  return ffi::Error::Success();
}

// An output's data, or null for an output of 0 elements (a part not asked for).
template <typename B>
auto data_or_null(B& buf) -> decltype(buf->typed_data()) {
  return buf->element_count() == 0 ? nullptr : buf->typed_data();
}

// The parts are all there (as long as the force) or all absent (0 elements).
inline bool sized(ffi::ResultBuffer<ffi::F64>& force, ffi::ResultBuffer<ffi::F64>& hyst,
                  ffi::ResultBuffer<ffi::F64>& lag, ffi::ResultBuffer<ffi::F64>& viscous,
                  ffi::ResultBuffer<ffi::S32>& depth) {
  const size_t n = hyst->element_count();
  return (n == 0 || n == force->element_count()) && lag->element_count() == n &&
         viscous->element_count() == n && depth->element_count() == n;
}

ffi::Error ForwardImpl(ffi::Buffer<ffi::F64> t, ffi::Buffer<ffi::F64> x,
                       ffi::Buffer<ffi::F64> v, ffi::Buffer<ffi::F64> params,
                       ffi::ResultBuffer<ffi::F64> force, ffi::ResultBuffer<ffi::F64> hyst,
                       ffi::ResultBuffer<ffi::F64> lag, ffi::ResultBuffer<ffi::F64> viscous,
                       ffi::ResultBuffer<ffi::S32> depth, ffi::ResultBuffer<ffi::S32> overflow,
                       int64_t shape, int64_t stack_size, int64_t limit, int64_t has_v,
                       int64_t threads) {
  if (!sized(force, hyst, lag, viscous, depth)) {
    return ffi::Error::InvalidArgument("forward pass: the parts have a wrong size");
  }
  return Forward<double>(t, x, v, params, force->typed_data(), data_or_null(hyst),
                         data_or_null(lag), data_or_null(viscous), data_or_null(depth),
                         overflow, nullptr, nullptr, shape, stack_size, limit, has_v, threads);
}

ffi::Error ForwardJacImpl(ffi::Buffer<ffi::F64> t, ffi::Buffer<ffi::F64> x,
                          ffi::Buffer<ffi::F64> v, ffi::Buffer<ffi::F64> params,
                          ffi::ResultBuffer<ffi::F64> force, ffi::ResultBuffer<ffi::F64> hyst,
                          ffi::ResultBuffer<ffi::F64> lag, ffi::ResultBuffer<ffi::F64> viscous,
                          ffi::ResultBuffer<ffi::S32> depth, ffi::ResultBuffer<ffi::S32> overflow,
                          ffi::ResultBuffer<ffi::F64> jac_force,
                          ffi::ResultBuffer<ffi::F64> jac_hyst, int64_t shape,
                          int64_t stack_size, int64_t limit, int64_t has_v, int64_t threads) {
  if (!sized(force, hyst, lag, viscous, depth) ||
      (jac_hyst->element_count() != 0 &&
       jac_hyst->element_count() != jac_force->element_count())) {
    return ffi::Error::InvalidArgument("forward pass: the parts have a wrong size");
  }
  return Forward<D>(t, x, v, params, force->typed_data(), data_or_null(hyst),
                    data_or_null(lag), data_or_null(viscous), data_or_null(depth), overflow,
                    jac_force->typed_data(), data_or_null(jac_hyst), shape, stack_size, limit,
                    has_v, threads);
}

}  // namespace

#define JAXFRIC_FORWARD_ARGS                         \
  ffi::Ffi::Bind()                                   \
      .Arg<ffi::Buffer<ffi::F64>>() /* t */          \
      .Arg<ffi::Buffer<ffi::F64>>() /* x */          \
      .Arg<ffi::Buffer<ffi::F64>>() /* v */          \
      .Arg<ffi::Buffer<ffi::F64>>() /* params */     \
      .Ret<ffi::Buffer<ffi::F64>>() /* force */      \
      .Ret<ffi::Buffer<ffi::F64>>() /* hysteresis */ \
      .Ret<ffi::Buffer<ffi::F64>>() /* lag */        \
      .Ret<ffi::Buffer<ffi::F64>>() /* viscous */    \
      .Ret<ffi::Buffer<ffi::S32>>() /* depth */      \
      .Ret<ffi::Buffer<ffi::S32>>() /* overflow */

#define JAXFRIC_FORWARD_ATTRS     \
  .Attr<int64_t>("shape")         \
      .Attr<int64_t>("stack_size") \
      .Attr<int64_t>("limit")      \
      .Attr<int64_t>("has_v")      \
      .Attr<int64_t>("threads")

XLA_FFI_DEFINE_HANDLER_SYMBOL(JaxfricForwardPass, ForwardImpl,
                              JAXFRIC_FORWARD_ARGS JAXFRIC_FORWARD_ATTRS);

XLA_FFI_DEFINE_HANDLER_SYMBOL(JaxfricForwardJacobian, ForwardJacImpl,
                              JAXFRIC_FORWARD_ARGS
                                  .Ret<ffi::Buffer<ffi::F64>>()  // d force / d params
                                  .Ret<ffi::Buffer<ffi::F64>>()  // d hysteresis / d params
                                      JAXFRIC_FORWARD_ATTRS);
