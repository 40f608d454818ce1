// The N-element GMS's element recursion as XLA FFI handlers for the CPU (jaxfric/_kernel).
//
// `GMS._element_forces` (jaxfric/_models/gms.py) is a scan over the samples of one update
// per element: stick (the element force grows with the step, clipped at its cap), start
// to slip where the force meets the limit within the sample, or relax towards its share
// of the Stribeck curve. The smooth per-sample inputs (the Stribeck value s, the rate
// C*dt/|s|, the previous sample's s) are computed by JAX, vectorised; this loop is the
// sequential part only, with the same float64 arithmetic and the same discrete decisions
// (comparisons of values).
//
// The second handler also returns the derivatives, in forward mode: every element carries
// P + 2 tangents, the P directions of the parameters all elements share (given as the
// tangents of s, rate, s_prev and the cap factor, computed by JAX) and one for its own nu
// and one for its own k (an element's force depends on no other element's). Each
// derivative follows JAX's rules for the operations of `GMS._update` (`jnp.clip`: half to
// each side at a tie, as lax.max and lax.min; `abs`: +1 at 0; `safe_div`: 0 where the
// denominator is 0), and only the branch the element takes is differentiated, as the JVP
// of `jnp.where` selects it.
//
// Inputs: dx, s, d, same, rate, s_prev (n) float64 (d the direction -1, 0, 1; same 1.0 where
// the sample moves in the direction of the one before, else 0.0), nu, k (N) float64, capf
// () float64 (the cap of an element is nu_i * capf); for the Jacobian also ds, drate,
// ds_prev (n, P) and dcapf (P) float64. Outputs: force (n), the summed element force; for
// the Jacobian also jac_nu, jac_k (n, N) (each element's force with respect to its own nu
// and k) and jac_shared (n, P) (the summed force along each shared direction).

#include <cmath>
#include <cstdint>
#include <initializer_list>
#include <vector>

#include "xla/ffi/api/ffi.h"

namespace ffi = xla::ffi;

namespace {

// lax.max and lax.min: a NaN on either side gives NaN (std::fmax would drop it).
inline double vmax(double a, double b) { return a != a || b != b ? NAN : (a > b ? a : b); }
inline double vmin(double a, double b) { return a != a || b != b ? NAN : (a < b ? a : b); }

// d max(x, y) / d x as lax.max's JVP: 1 where x is the larger, 1/2 at a tie, else 0.
inline double share(double x, double ans, double y) {
  return (x == ans ? 1.0 : 0.0) / (y == ans ? 2.0 : 1.0);
}

// The recursion; with `jac` null only the forces (P unused).
void run(int64_t n, int64_t N, int64_t P, const double* dx, const double* s, const double* d,
         const double* same, const double* rate, const double* s_prev, const double* nu,
         const double* k, double capf, const double* ds, const double* drate,
         const double* ds_prev, const double* dcapf, double* force, double* jac_nu,
         double* jac_k, double* jac_shared) {
  const bool jac = jac_nu != nullptr;
  const int64_t D = jac ? P + 2 : 0;  // tangents per element: P shared, own nu, own k
  const int64_t inu = P, ik = P + 1;
  std::vector<double> F(N, 0.0), Fd(N * D, 0.0);
  std::vector<char> slipping(N, 0);
  // per-sample scratch (tangents of length D; own directions of the shared inputs are 0)
  std::vector<double> sd(D, 0.0), rd(D, 0.0), spd(D, 0.0), cd(D, 0.0), ed(D, 0.0);
  std::vector<double> td(D), fst(D), ld(D), l0d(D), g0d(D), dend(D), qd(D), thd(D), md(D),
      argd(D), capd(D), out(D);
  for (int64_t t = 0; t < n; ++t) {
    const double sv = s[t], rv = rate[t], spv = s_prev[t], dxv = dx[t], dv = d[t];
    const bool same_t = same[t] != 0.0;
    const double ev = std::exp(-rv);
    const double as = std::fabs(sv), asp = std::fabs(spv);
    const double sg = sv >= 0.0 ? 1.0 : -1.0, sgp = spv >= 0.0 ? 1.0 : -1.0;
    if (jac) {
      for (int64_t j = 0; j < P; ++j) {
        sd[j] = ds[t * P + j];
        rd[j] = drate[t * P + j];
        spd[j] = ds_prev[t * P + j];
        cd[j] = dcapf[j];
        ed[j] = -ev * rd[j];
      }
    }
    double total = 0.0;
    for (int64_t j = 0; j < (jac ? P : 0); ++j) jac_shared[t * P + j] = 0.0;
    for (int64_t i = 0; i < N; ++i) {
      double* fd = jac ? &Fd[i * D] : nullptr;
      const double Fv = F[i], nuv = nu[i], kv = k[i];
      const bool slip = slipping[i] && same_t;
      const double tv = nuv * sv;  // target
      const double fsv = Fv + kv * dxv;  // stick force before the clip
      const double lv = nuv * as;  // limit
      const bool starts = dv != 0.0 && dv * fsv > lv;
      if (jac && (slip || starts)) {  // the target's tangents (the stick branch has none)
        for (int64_t j = 0; j < D; ++j) td[j] = nuv * sd[j];
        td[inu] = sv;
      }
      double Fn;
      if (slip) {  // relax towards the target
        Fn = tv + (Fv - tv) * ev;
        if (jac) {
          for (int64_t j = 0; j < D; ++j) out[j] = td[j] + (fd[j] - td[j]) * ev + (Fv - tv) * ed[j];
        }
      } else if (starts) {  // slips from where within the sample the limit was met
        const double l0v = nuv * asp;
        const double g0v = l0v - dv * Fv;
        const double denv = g0v - (lv - dv * fsv);
        double qv = 0.0, thv = 0.0;
        if (jac) {
          for (int64_t j = 0; j < D; ++j) {
            fst[j] = fd[j];
            ld[j] = nuv * sg * sd[j];
            l0d[j] = nuv * sgp * spd[j];
          }
          fst[ik] += dxv;
          ld[inu] = as;
          l0d[inu] = asp;
          for (int64_t j = 0; j < D; ++j) {
            g0d[j] = l0d[j] - dv * fd[j];
            dend[j] = g0d[j] - (ld[j] - dv * fst[j]);
            thd[j] = 0.0;
          }
        }
        if (g0v > 0.0) {
          qv = denv == 0.0 ? 0.0 : g0v / denv;
          const double m = vmax(0.0, qv), c = vmin(1.0, m);
          thv = c;
          if (jac && denv != 0.0) {
            const double w = share(qv, m, 0.0) * share(m, c, 1.0);
            for (int64_t j = 0; j < D; ++j) {
              qd[j] = g0d[j] / denv + (-dend[j] * g0v) * (1.0 / (denv * denv));
              thd[j] = w * qd[j];
            }
          }
        }
        const double mv = dv * (l0v + thv * (lv - l0v));
        const double argv = -(1.0 - thv) * rv;
        const double e2 = std::exp(argv);
        Fn = tv + (mv - tv) * e2;
        if (jac) {
          for (int64_t j = 0; j < D; ++j) {
            md[j] = dv * (l0d[j] + thd[j] * (lv - l0v) + thv * (ld[j] - l0d[j]));
            argd[j] = thd[j] * rv - (1.0 - thv) * rd[j];
            out[j] = td[j] + (md[j] - td[j]) * e2 + (mv - tv) * e2 * argd[j];
          }
        }
      } else {  // sticks: clip(f, -cap, cap) = min(cap, max(-cap, f))
        const double cv = nuv * capf;
        const double m = vmax(-cv, fsv), c = vmin(cv, m);
        Fn = c;
        if (jac) {
          const double a_f = share(fsv, m, -cv), a_lo = share(-cv, m, fsv);
          const double b_m = share(m, c, cv), b_hi = share(cv, c, m);
          for (int64_t j = 0; j < D; ++j) {
            capd[j] = nuv * cd[j];
            fst[j] = fd[j];
          }
          capd[inu] = capf;
          fst[ik] += dxv;
          for (int64_t j = 0; j < D; ++j) {
            out[j] = b_m * (a_f * fst[j] - a_lo * capd[j]) + b_hi * capd[j];
          }
        }
      }
      F[i] = Fn;
      slipping[i] = slip || starts;
      total += Fn;
      if (jac) {
        for (int64_t j = 0; j < D; ++j) fd[j] = out[j];
        for (int64_t j = 0; j < P; ++j) jac_shared[t * P + j] += out[j];
        jac_nu[t * N + i] = out[inu];
        jac_k[t * N + i] = out[ik];
      }
    }
    force[t] = total;
  }
}

bool lengths_ok(int64_t n, std::initializer_list<const ffi::Buffer<ffi::F64>*> bufs) {
  for (auto* b : bufs) {
    if (b->element_count() != static_cast<size_t>(n)) return false;
  }
  return true;
}

// The inputs both handlers share: per-sample arrays of one length, nu and k of another,
// one cap factor, a force per sample.
bool inputs_ok(const ffi::Buffer<ffi::F64>& dx, const ffi::Buffer<ffi::F64>& s,
               const ffi::Buffer<ffi::F64>& d, const ffi::Buffer<ffi::F64>& same,
               const ffi::Buffer<ffi::F64>& rate, const ffi::Buffer<ffi::F64>& s_prev,
               const ffi::Buffer<ffi::F64>& nu, const ffi::Buffer<ffi::F64>& k,
               const ffi::Buffer<ffi::F64>& capf, size_t force) {
  const int64_t n = static_cast<int64_t>(dx.element_count());
  return lengths_ok(n, {&s, &d, &same, &rate, &s_prev}) &&
         k.element_count() == nu.element_count() && capf.element_count() == 1 &&
         force == static_cast<size_t>(n);
}

ffi::Error GmsImpl(ffi::Buffer<ffi::F64> dx, ffi::Buffer<ffi::F64> s, ffi::Buffer<ffi::F64> d,
                   ffi::Buffer<ffi::F64> same, ffi::Buffer<ffi::F64> rate,
                   ffi::Buffer<ffi::F64> s_prev, ffi::Buffer<ffi::F64> nu,
                   ffi::Buffer<ffi::F64> k, ffi::Buffer<ffi::F64> capf,
                   ffi::ResultBuffer<ffi::F64> force) {
  const int64_t n = static_cast<int64_t>(dx.element_count());
  const int64_t N = static_cast<int64_t>(nu.element_count());
  if (!inputs_ok(dx, s, d, same, rate, s_prev, nu, k, capf, force->element_count())) {
    return ffi::Error::InvalidArgument("gms elements: inconsistent lengths");
  }
  run(n, N, 0, dx.typed_data(), s.typed_data(), d.typed_data(), same.typed_data(),
      rate.typed_data(), s_prev.typed_data(), nu.typed_data(), k.typed_data(),
      capf.typed_data()[0], nullptr, nullptr, nullptr, nullptr, force->typed_data(), nullptr,
      nullptr, nullptr);
  return ffi::Error::Success();
}

ffi::Error GmsJacImpl(ffi::Buffer<ffi::F64> dx, ffi::Buffer<ffi::F64> s,
                      ffi::Buffer<ffi::F64> d, ffi::Buffer<ffi::F64> same,
                      ffi::Buffer<ffi::F64> rate, ffi::Buffer<ffi::F64> s_prev,
                      ffi::Buffer<ffi::F64> nu, ffi::Buffer<ffi::F64> k,
                      ffi::Buffer<ffi::F64> capf, ffi::Buffer<ffi::F64> ds,
                      ffi::Buffer<ffi::F64> drate, ffi::Buffer<ffi::F64> ds_prev,
                      ffi::Buffer<ffi::F64> dcapf, ffi::ResultBuffer<ffi::F64> force,
                      ffi::ResultBuffer<ffi::F64> jac_nu, ffi::ResultBuffer<ffi::F64> jac_k,
                      ffi::ResultBuffer<ffi::F64> jac_shared) {
  const int64_t n = static_cast<int64_t>(dx.element_count());
  const int64_t N = static_cast<int64_t>(nu.element_count());
  const int64_t P = static_cast<int64_t>(dcapf.element_count());
  const size_t nP = static_cast<size_t>(n * P), nN = static_cast<size_t>(n * N);
  if (!inputs_ok(dx, s, d, same, rate, s_prev, nu, k, capf, force->element_count()) ||
      ds.element_count() != nP || drate.element_count() != nP || ds_prev.element_count() != nP
      || jac_shared->element_count() != nP || jac_nu->element_count() != nN ||
      jac_k->element_count() != nN) {
    return ffi::Error::InvalidArgument("gms elements: inconsistent lengths");
  }
  run(n, N, P, dx.typed_data(), s.typed_data(), d.typed_data(), same.typed_data(),
      rate.typed_data(), s_prev.typed_data(), nu.typed_data(), k.typed_data(),
      capf.typed_data()[0], ds.typed_data(), drate.typed_data(), ds_prev.typed_data(),
      dcapf.typed_data(), force->typed_data(), jac_nu->typed_data(), jac_k->typed_data(),
      jac_shared->typed_data());
  return ffi::Error::Success();
}

}  // namespace

#define JAXFRIC_GMS_ARGS                          \
  ffi::Ffi::Bind()                                \
      .Arg<ffi::Buffer<ffi::F64>>() /* dx */      \
      .Arg<ffi::Buffer<ffi::F64>>() /* s */       \
      .Arg<ffi::Buffer<ffi::F64>>() /* d */       \
      .Arg<ffi::Buffer<ffi::F64>>() /* same */    \
      .Arg<ffi::Buffer<ffi::F64>>() /* rate */    \
      .Arg<ffi::Buffer<ffi::F64>>() /* s_prev */  \
      .Arg<ffi::Buffer<ffi::F64>>() /* nu */      \
      .Arg<ffi::Buffer<ffi::F64>>() /* k */       \
      .Arg<ffi::Buffer<ffi::F64>>() /* capf */

XLA_FFI_DEFINE_HANDLER_SYMBOL(JaxfricGmsElements, GmsImpl,
                              JAXFRIC_GMS_ARGS.Ret<ffi::Buffer<ffi::F64>>() /* force */);

XLA_FFI_DEFINE_HANDLER_SYMBOL(JaxfricGmsJacobian, GmsJacImpl,
                              JAXFRIC_GMS_ARGS
                                  .Arg<ffi::Buffer<ffi::F64>>()  // ds
                                  .Arg<ffi::Buffer<ffi::F64>>()  // drate
                                  .Arg<ffi::Buffer<ffi::F64>>()  // ds_prev
                                  .Arg<ffi::Buffer<ffi::F64>>()  // dcapf
                                  .Ret<ffi::Buffer<ffi::F64>>()  // force
                                  .Ret<ffi::Buffer<ffi::F64>>()  // jac_nu
                                  .Ret<ffi::Buffer<ffi::F64>>()  // jac_k
                                  .Ret<ffi::Buffer<ffi::F64>>());  // jac_shared
