// Batch helpers shared by the FFI handlers of jaxfric/_kernel (events.cc, forward.cc).
//
// A handler's inputs have leading batch dimensions (numpy broadcasting: a dimension of 1
// repeats, as JAX's vmap with vmap_method="expand_dims" passes unbatched inputs) and one or
// two trailing data dimensions; its outputs have the full batch dimensions. `row_offsets`
// maps each output row to an input row; `for_rows` runs a row function over all rows, on
// several std::threads when each gets enough work, the rows handed out as threads get free.

#ifndef JAXFRIC_KERNEL_ROWS_H_
#define JAXFRIC_KERNEL_ROWS_H_

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <thread>
#include <vector>

namespace jaxfric {

// Offsets (in rows) of every output batch row into an input with batch dims `in` (numpy
// broadcasting of leading dimensions; a dimension of 1 repeats).
inline bool row_offsets(const std::vector<int64_t>& out, std::vector<int64_t> in,
                 std::vector<int64_t>& offsets) {
  if (in.size() > out.size()) return false;
  in.insert(in.begin(), out.size() - in.size(), 1);
  const size_t rank = out.size();
  std::vector<int64_t> stride(rank, 0);
  int64_t acc = 1;
  for (size_t k = rank; k-- > 0;) {
    if (in[k] != 1 && in[k] != out[k]) return false;
    stride[k] = in[k] == 1 ? 0 : acc;
    acc *= in[k];
  }
  int64_t rows = 1;
  for (int64_t d : out) rows *= d;
  offsets.assign(rows, 0);
  for (int64_t b = 0; b < rows; ++b) {
    int64_t rest = b, off = 0;
    for (size_t k = rank; k-- > 0;) {
      off += (rest % out[k]) * stride[k];
      rest /= out[k];
    }
    offsets[b] = off;
  }
  return true;
}

template <typename B>
std::vector<int64_t> lead_dims(const B& buf, size_t trailing) {
  auto d = buf.dimensions();
  return std::vector<int64_t>(d.begin(), d.end() - trailing);
}

// Run work(lo, hi) over rows [0, rows) on at most `threads` threads, each with at least
// 2^log2_share samples (n per row): starting a thread costs tens of microseconds, so
// smaller shares run on the calling thread. The threads take runs of rows from a shared
// counter as they finish their last (not fixed halves): on a machine where another process
// holds a core, or where rows differ in work, no thread waits idle for a slow one.
template <typename F>
void for_rows(int64_t rows, int64_t n, int64_t threads, int log2_share, F work) {
  const int64_t nthreads = std::min<int64_t>(
      std::min<int64_t>(threads, rows), std::max<int64_t>(1, (rows * n) >> log2_share));
  if (nthreads <= 1) {
    work(0, rows);
    return;
  }
  // Runs of about 2^log2_share samples, and at least 8 runs per thread.
  const int64_t grain = std::max<int64_t>(
      1, std::min<int64_t>((int64_t{1} << log2_share) / std::max<int64_t>(n, 1),
                           rows / (8 * nthreads)));
  std::atomic<int64_t> next{0};
  auto worker = [&]() {
    for (;;) {
      const int64_t lo = next.fetch_add(grain, std::memory_order_relaxed);
      if (lo >= rows) return;
      work(lo, std::min(rows, lo + grain));
    }
  };
  std::vector<std::thread> pool;
  for (int64_t k = 1; k < nthreads; ++k) pool.emplace_back(worker);
  worker();
  for (auto& th : pool) th.join();
}

}  // namespace jaxfric

#endif  // JAXFRIC_KERNEL_ROWS_H_
