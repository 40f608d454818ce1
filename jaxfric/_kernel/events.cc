// The two-state model's event pass as an XLA FFI handler for the CPU (jaxfric/_kernel).
//
// The same algorithm as the pure-JAX event loop of jaxfric/_models/two_state.py
// (`_event_loop`, `TwoState._push`, `TwoState._close`), one sample after another, with
// the same arithmetic (IEEE float64, no fast-math) so that its records are bit-identical:
//
//   table  (..., n + 1, 4) int32: per event sample j the entry in use after the event (a
//          reversal's sample index, -1 for the zero state), the stack depth, the parent of
//          the entry pushed at j, and the length of the popped list so far; 0 elsewhere.
//          Row n holds the final state (active, depth, -1, popped length), as the JAX loop
//          leaves it.
//   popped (..., n + K) int32: the sample indices of the entries closed, in order; -1 after.
//   overflow (...) int32: entries dropped because the buffer of K entries was full.
//   filled (..., n, 3) int32: per sample the state after the last event at or before it
//          (active, depth, popped length); the zero state (-1, 1, 0) before the first.
//
// Inputs (float64 unless said): x, s, reversal (bool), x_prev, s_r, all (..., n), and l1
// (...). Leading dimensions are batch dimensions; an input's batch dimension of 1 is
// broadcast (as JAX's vmap with vmap_method="expand_dims" passes unbatched inputs). Batch
// rows run on std::threads when there are several rows and enough samples.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <thread>
#include <vector>

#include "rows.h"
#include "stack.h"
#include "xla/ffi/api/ffi.h"

namespace ffi = xla::ffi;

namespace {

using jaxfric::for_rows;
using jaxfric::Push;
using jaxfric::push_slot;
using jaxfric::lead_dims;
using jaxfric::row_offsets;

inline double safe_div(double num, double den) { return den == 0.0 ? 0.0 : num / den; }

struct Row {
  const double* x;
  const double* s;
  const bool* rev;
  const double* xp;
  const double* sr;
  double l1;
  int32_t* table;
  int32_t* popped;
  int32_t* overflow;
  int32_t* filled;
};

// One trajectory of n samples with a memory of K entries (circular buffer, logical entry i
// in slot (base + i) % K, as `MemoryStack`).
void run_row(const Row& r, int64_t n, int32_t K) {
  std::fill(r.table, r.table + (n + 1) * 4, 0);
  std::fill(r.popped, r.popped + n + K, -1);
  std::vector<double> X(K, 0.0), S(K, 0.0), TH(K, 0.0);
  std::vector<char> CL(K, 0);
  std::vector<int32_t> REF(K, -1);
  X[0] = r.x[0];
  int32_t base = 0, depth = 1, ovf = 0, npop = 0;
  bool zero_bottom = true;
  int32_t active = -1;
  const double l1 = r.l1;
  for (int64_t j = 0; j < n; ++j) {
    int32_t top = (base + depth - 1) % K;
    const bool reversal = r.rev[j];
    bool event = reversal;
    if (!event) {  // `TwoState._top_closes`
      event = depth >= 2 && CL[top] && (depth >= 3 || zero_bottom) &&
              safe_div(r.x[j] - X[top], r.s[j] - S[top]) >= TH[top];
    }
    if (event) {
      const int32_t parent = REF[top];
      if (reversal) {  // `TwoState._push` (Rule 1, wiping-out, overflow)
        const double x_r = r.xp[j], s_r = r.sr[j];
        const double den = s_r - S[top];
        const double theta = safe_div(std::fabs(x_r - X[top]), std::fabs(den));
        const bool wipe = theta > l1;
        const Push p = push_slot(wipe, top, base, depth, K);
        const int32_t slot = p.slot;
        X[slot] = x_r;
        S[slot] = s_r;
        TH[slot] = theta;
        CL[slot] = theta <= l1;
        REF[slot] = static_cast<int32_t>(j);
        if (p.over || (wipe && depth > 1)) zero_bottom = false;
        ovf += p.over ? 1 : 0;
        base = p.base;
        depth = p.depth;
      }
      // `TwoState._close` (Rules 2 and 3): the run of closing levels top, top-2, ...
      const int32_t pushed_depth = depth;
      int32_t lowest = -1;
      for (int32_t level = depth - 1; level >= 1; level -= 2) {
        const int32_t sl = (base + level) % K;
        const bool valid = CL[sl] && (level >= 2 || zero_bottom);
        if (valid && safe_div(r.x[j] - X[sl], r.s[j] - S[sl]) >= TH[sl]) {
          lowest = level;
        } else {
          break;
        }
      }
      if (lowest >= 1) depth = (lowest == 1 ? 0 : lowest - 2) + 1;
      for (int32_t i = 0; i < pushed_depth - depth; ++i) {
        r.popped[npop + i] = REF[(base + depth + i) % K];
      }
      npop += pushed_depth - depth;
      top = (base + depth - 1) % K;
      active = REF[top];
      int32_t* row = r.table + 4 * j;
      row[0] = active;
      row[1] = depth;
      row[2] = parent;
      row[3] = npop;
    }
    int32_t* f = r.filled + 3 * j;
    f[0] = active;
    f[1] = depth;
    f[2] = npop;
  }
  int32_t* last = r.table + 4 * n;
  last[0] = REF[(base + depth - 1) % K];
  last[1] = depth;
  last[2] = -1;
  last[3] = npop;
  *r.overflow = ovf;
}

ffi::Error EventPassImpl(ffi::Buffer<ffi::F64> x, ffi::Buffer<ffi::F64> s,
                         ffi::Buffer<ffi::PRED> rev, ffi::Buffer<ffi::F64> xp,
                         ffi::Buffer<ffi::F64> sr, ffi::Buffer<ffi::F64> l1,
                         ffi::ResultBuffer<ffi::S32> table, ffi::ResultBuffer<ffi::S32> popped,
                         ffi::ResultBuffer<ffi::S32> overflow,
                         ffi::ResultBuffer<ffi::S32> filled, int64_t stack_size,
                         int64_t threads) {
  auto xd = x.dimensions();
  if (xd.size() < 1) return ffi::Error::InvalidArgument("event pass: x must have rank >= 1");
  const int64_t n = xd.back();
  const int32_t K = static_cast<int32_t>(stack_size);
  if (n < 1 || K < 1) return ffi::Error::InvalidArgument("event pass: empty input");
  const std::vector<int64_t> out = lead_dims(*overflow, 0);
  std::vector<int64_t> ox, os, orv, oxp, osr, ol;
  const bool ok = row_offsets(out, lead_dims(x, 1), ox) && row_offsets(out, lead_dims(s, 1), os) &&
                  row_offsets(out, lead_dims(rev, 1), orv) &&
                  row_offsets(out, lead_dims(xp, 1), oxp) &&
                  row_offsets(out, lead_dims(sr, 1), osr) && row_offsets(out, lead_dims(l1, 0), ol);
  if (!ok) return ffi::Error::InvalidArgument("event pass: batch dimensions do not broadcast");
  if (s.dimensions().back() != n || rev.dimensions().back() != n ||
      xp.dimensions().back() != n || sr.dimensions().back() != n) {
    return ffi::Error::InvalidArgument("event pass: lengths differ");
  }
  const int64_t rows = static_cast<int64_t>(ox.size());
  auto work = [&](int64_t lo, int64_t hi) {
    for (int64_t b = lo; b < hi; ++b) {
      Row r{x.typed_data() + ox[b] * n,  s.typed_data() + os[b] * n,
            rev.typed_data() + orv[b] * n, xp.typed_data() + oxp[b] * n,
            sr.typed_data() + osr[b] * n,  l1.typed_data()[ol[b]],
            table->typed_data() + b * (n + 1) * 4, popped->typed_data() + b * (n + K),
            overflow->typed_data() + b,     filled->typed_data() + b * n * 3};
      run_row(r, n, K);
    }
  };
  for_rows(rows, n, threads, 16, work);
  return ffi::Error::Success();
}

}  // namespace

XLA_FFI_DEFINE_HANDLER_SYMBOL(JaxfricEventPass, EventPassImpl,
                              ffi::Ffi::Bind()
                                  .Arg<ffi::Buffer<ffi::F64>>()   // x
                                  .Arg<ffi::Buffer<ffi::F64>>()   // s
                                  .Arg<ffi::Buffer<ffi::PRED>>()  // reversal
                                  .Arg<ffi::Buffer<ffi::F64>>()   // x_prev
                                  .Arg<ffi::Buffer<ffi::F64>>()   // s_r
                                  .Arg<ffi::Buffer<ffi::F64>>()   // l1
                                  .Ret<ffi::Buffer<ffi::S32>>()   // table
                                  .Ret<ffi::Buffer<ffi::S32>>()   // popped
                                  .Ret<ffi::Buffer<ffi::S32>>()   // overflow
                                  .Ret<ffi::Buffer<ffi::S32>>()   // filled
                                  .Attr<int64_t>("stack_size")
                                  .Attr<int64_t>("threads"));
