// The memory stack's placement of a new entry, shared by the kernels of jaxfric/_kernel
// (events.cc, forward.cc): a circular buffer of K entries, logical entry i in slot
// (base + i) % K, as `MemoryStack`.

#ifndef JAXFRIC_KERNEL_STACK_H_
#define JAXFRIC_KERNEL_STACK_H_

#include <cstdint>

namespace jaxfric {

// Where `TwoState._push` puts a reversal: on top of the stack, or, when it wipes out
// (theta > l1), right above the top entry's base level `top`; when the buffer is full the
// bottom entry is dropped (`over`).
struct Push {
  int32_t base, depth, slot;
  bool over;
};

inline Push push_slot(bool wipe, int32_t top, int32_t base, int32_t depth, int32_t K) {
  int32_t nb = wipe ? top : base;
  int32_t nd = (wipe ? 1 : depth) + 1;
  const bool over = nd > K;
  if (over) {
    nb = (nb + 1) % K;
    nd = K;
  }
  return {nb, nd, (nb + nd - 1) % K, over};
}

}  // namespace jaxfric

#endif  // JAXFRIC_KERNEL_STACK_H_
