"""The two-state GMS-based model (paper Sec. 4; docs/algorithm.md section 4).

Structure, chosen for speed and clean gradients:

* the event logic (reversal detection, stack push with wiping-out and overflow, the
  loop-closure cascade) is the only sequential part, and it is discrete: it runs on
  stopped gradients in a ``lax.while_loop`` that jumps from event to event, testing a
  block of samples at once (`_event_loop`), and records per event the entry in use, the
  parent of a pushed entry and the entries popped;
* everything smooth is computed from those records, vectorised and differentiable: the
  branch-start forces ``h`` as prefix sums over pushes minus pops, evaluated on the list
  of reversals only (``Motion.max_reversals`` slots, a static bound), ``F_h`` from the
  entry in use (Eq. 32), and ``F_l`` as a linear recurrence (exact decay).

``TwoState.step`` composes the same helpers (`_push`, `_close`, `_branch`) for one sample,
for closed-loop use; tests check both give the same forces.
"""

import functools
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Bool, Float, Int

from .. import _kernel
from .._fields import param
from .._kernel import forward as _forward_kernel
from .._numerics import linear_recurrence, running_max, running_sum, safe_div
from .._shapes import AbstractShape
from .._stribeck import Stribeck
from ..motion import consistent_velocity, Motion
from ._base import AbstractFrictionModel, SimResult


class MemoryStack(eqx.Module):
    """Reversal points in fixed-size arrays used as a circular buffer.

    Logical entry ``i`` (0 = bottom, ``depth - 1`` = top) lives in slot ``(base + i) % K``.
    Wiping-out and overflow only move `base`, and a push writes one slot, so the per-sample
    cost does not grow with ``K`` except for the vectorised loop-closure test.

    Per entry: `x` (m), `h` = F_h at the start of the branch (N), `s` = the Stribeck rest
    value at the reversal (N; 0 for the zero state), `theta` = its presliding extent
    ``|x - x_below| / |s - s_below|`` (m/N), `closable` = ``theta <= l1`` (Eq. 25/29),
    `ref` = the sample index of the reversal that pushed it (-1 for the zero state and in
    `TwoState.step`, which has no sample index). `zero_bottom` says whether the bottom
    entry is the zero state; `overflow` counts the entries dropped because the buffer was
    full.
    """

    x: Float[Array, " K"]
    h: Float[Array, " K"]
    s: Float[Array, " K"]
    theta: Float[Array, " K"]
    closable: Bool[Array, " K"]
    ref: Int[Array, " K"]
    base: Int[Array, ""]
    depth: Int[Array, ""]
    zero_bottom: Bool[Array, ""]
    overflow: Int[Array, ""]

    @classmethod
    def zero_state(cls, size: int, x0: ArrayLike) -> "MemoryStack":
        x0 = jnp.asarray(x0)
        zeros = jnp.zeros((size,), x0.dtype)
        return cls(
            x=zeros.at[0].set(x0),
            h=zeros,
            s=zeros,
            theta=zeros,
            closable=jnp.zeros((size,), bool),
            ref=jnp.full((size,), -1, jnp.int32),
            base=jnp.zeros((), jnp.int32),
            depth=jnp.ones((), jnp.int32),
            zero_bottom=jnp.ones((), bool),
            overflow=jnp.zeros((), jnp.int32),
        )

    @property
    def top(self) -> Array:
        """Slot of the top entry."""
        return (self.base + self.depth - 1) % self.x.shape[0]

    def levels(self) -> Array:
        """Logical index of every slot (meaningful where it is < `depth`)."""
        size = self.x.shape[0]
        return (jnp.arange(size, dtype=jnp.int32) - self.base) % size

    def top_entry(self) -> tuple[Array, Array, Array]:
        top = self.top
        return self.x[top], self.h[top], self.s[top]


class TwoStateState(eqx.Module):
    """Per-sample state for `TwoState.step`: the memory, F_l (N) and the previous sample."""

    stack: MemoryStack
    lag: Array
    last_d: Array
    x_prev: Array
    s_prev: Array


class TwoState(AbstractFrictionModel):
    """Two-state GMS-based friction model: ``F = F_h + F_l + sigma2*v``.

    **Arguments:**

    - `stribeck`: the `Stribeck` curve (Fs, Fc, Vs, delta).
    - `shape`: the presliding shape (`PaperShape`, `PowerShape`, ...); holds ``l1`` (m/N).
    - `sigma2`: viscous coefficient, N s/m.
    - `C`: attraction parameter of the friction lag, N/s.
    - `stack_size`: capacity of the reversal memory (static, >= 3). Wiping-out keeps the
      stack shallow in practice; when it overflows the oldest entries are dropped and
      counted (`SimResult.overflow`, and a warning from `jaxfric.simulate`).
    """

    stribeck: Stribeck
    shape: AbstractShape
    sigma2: Array = param("N s/m", constraint="positive")
    C: Array = param("N/s", constraint="positive", role="lag")
    stack_size: int = eqx.field(static=True, default=16)
    uses_reversal_bound: ClassVar[bool] = True

    def __check_init__(self):
        if self.stack_size < 3:
            raise ValueError(f"stack_size must be >= 3, got {self.stack_size}")

    # ---- shared pieces (used by both `step` and `_simulate`) ----------------------------

    def _branch(self, x, s, x_e, h_e, s_e):
        """F_h on the branch of entry e (Eq. 32), its argument xi, and gamma(xi)."""
        den = s - s_e
        xi = safe_div(x - x_e, den)
        p, _, g = self.shape.pi_kappa_gamma(xi, self.stribeck.Fs)
        return h_e + p * den, xi, g

    def _push(self, stack: MemoryStack, reversal, x_r, s_r, ref_r=-1, with_h=True) -> MemoryStack:
        """Rule 1 at reversal point ``x_r`` (rest value ``s_r``; `ref_r` its sample index),
        with wiping and overflow; nothing changes where `reversal` is false. With
        ``with_h=False`` the entry's `h` is left at 0 (the event pass does not need it)."""
        size = stack.x.shape[0]
        top = stack.top
        x_e, h_e, s_e = stack.top_entry()
        den = s_r - s_e
        # F_h at the reversal, in the v -> 0 limit s = s_r (MODEL_NOTES, traps).
        if with_h:
            h_r = h_e + self.shape.pi(safe_div(x_r - x_e, den), self.stribeck.Fs) * den
        else:
            h_r = jnp.zeros_like(h_e)
        theta = safe_div(jnp.abs(x_r - x_e), jnp.abs(den))
        # Wiping-out: a reversal outside presliding makes every entry below the current
        # branch start unreachable; that start becomes the bottom (it is kept).
        wipe = theta > self.shape.l1
        base = jnp.where(wipe, top, stack.base)
        depth = jnp.where(wipe, 1, stack.depth) + 1
        over = depth > size
        base = jnp.where(over, (base + 1) % size, base)
        depth = jnp.where(over, size, depth)
        base = jnp.where(reversal, base, stack.base)
        depth = jnp.where(reversal, depth, stack.depth)
        slot = (base + depth - 1) % size

        def put(a, value):
            return a.at[slot].set(jnp.where(reversal, value, a[slot]))

        dropped = reversal & (over | (wipe & (stack.depth > 1)))
        return MemoryStack(
            x=put(stack.x, x_r),
            h=put(stack.h, h_r),
            s=put(stack.s, s_r),
            theta=put(stack.theta, theta),
            closable=put(stack.closable, theta <= self.shape.l1),
            ref=put(stack.ref, jnp.asarray(ref_r, jnp.int32)),
            base=base,
            depth=depth,
            zero_bottom=stack.zero_bottom & ~dropped,
            overflow=stack.overflow + (reversal & over).astype(jnp.int32),
        )

    @staticmethod
    def _close(stack: MemoryStack, x, s) -> MemoryStack:
        """Rules 2 and 3: close every loop that position ``x`` (with Stribeck value ``s``)
        has closed, possibly several nested ones in one sample, without a loop.

        Levels ``top, top-2, ...`` (same direction as the current branch) are tested at
        once; the run of closed levels from the top down decides the new top.
        """
        size = stack.x.shape[0]
        lev = stack.levels()
        top = stack.depth - 1
        xi = safe_div(x - stack.x, s - stack.s)
        level = (lev >= 1) & (lev <= top) & ((top - lev) % 2 == 0)
        # Level 1 can close only onto the zero state (Rule 3); otherwise its lower
        # neighbour was dropped (wiping or overflow) and there is nothing to close onto.
        valid = stack.closable & ((lev >= 2) | stack.zero_bottom)
        blocked = level & ~(valid & (xi >= stack.theta))
        highest_blocked = jnp.max(jnp.where(blocked, lev, -1))
        lowest_closed = jnp.min(jnp.where(level & (lev > highest_blocked), lev, size))
        new_top = jnp.where(
            lowest_closed >= size,
            top,
            jnp.where(lowest_closed == 1, 0, lowest_closed - 2),
        )
        return eqx.tree_at(lambda st: st.depth, stack, (new_top + 1).astype(jnp.int32))

    def _events(self, stack, x, s, reversal, x_r, s_r) -> MemoryStack:
        """Rule 1 (push) then Rules 2-3 (closures) for one sample (`step`).

        Both are rare, so an ordinary sample only pays for a few scalar tests: the push
        runs under ``lax.cond`` on `reversal`, and the K-wide closure cascade only when the
        top level closes (a cascade always starts there).
        """
        stack = jax.lax.cond(
            reversal,
            lambda st: self._push(st, True, x_r, s_r),
            lambda st: st,
            stack,
        )
        return jax.lax.cond(
            self._top_closes(stack, x, s), lambda st: self._close(st, x, s), lambda st: st, stack
        )

    @staticmethod
    def _top_closes(stack: MemoryStack, x, s):
        """Whether position(s) `x` (Stribeck values `s`) close the top level: the test
        `_close` applies to it (level >= 1, closable, xi >= theta; level 1 needs the zero
        state below it). Vectorised over `x`, `s` for the same stack."""
        top = stack.top
        return (
            (stack.depth >= 2)
            & stack.closable[top]
            & ((stack.depth >= 3) | stack.zero_bottom)
            & (safe_div(x - stack.x[top], s - stack.s[top]) >= stack.theta[top])
        )

    def _event_pass(self, x, s, reversal, x_prev, s_r) -> "_Events":
        """The sequential part of a trajectory (see `_event_records`), on stopped
        gradients: everything it decides is discrete."""
        params, static = eqx.partition(self, eqx.is_array)
        params, x, s, x_prev, s_r = jax.lax.stop_gradient((params, x, s, x_prev, s_r))
        if _kernel.use_kernel(x, s, x_prev, s_r):  # the compiled CPU kernel (jaxfric._kernel)
            l1 = jax.lax.stop_gradient(self.shape.l1)
            return _Events(*_kernel.event_pass(x, s, reversal, x_prev, s_r, l1,
                                               self.stack_size))
        return _event_records(static)(params, x, s, reversal, x_prev, s_r)

    def _lag_coefficients(self, dt, s, d, prev_last_d, reversal, s_prev, gamma):
        """``F_l,n = a * F_l,n-1 + b`` (docs/algorithm.md section 4, step 4)."""
        moving = d != 0
        decay = jnp.exp(-self.C * safe_div(dt, jnp.abs(s)))
        a = jnp.where(reversal, 0.0, jnp.where(moving, decay, 1.0))
        # A direction-change step (a reversal or the first motion) charges nothing: s
        # leaves the rest value on the new side at xi = 0, where gamma = 0, and the step's
        # travel happens at the speed of its sample, after s has dropped.
        b = jnp.where(moving & (d != prev_last_d), 0.0, -gamma * (s - s_prev))
        return a, b

    # ---- per-sample API ---------------------------------------------------------------

    def init_state(self, x0: ArrayLike = 0.0) -> TwoStateState:
        x0 = jnp.asarray(x0, dtype=self.C.dtype)
        zero = jnp.zeros((), x0.dtype)
        return TwoStateState(
            stack=MemoryStack.zero_state(self.stack_size, x0),
            lag=zero,
            last_d=zero,
            x_prev=x0,
            s_prev=zero,
        )

    def step(self, state: TwoStateState, x, v, dt):
        x, v, dt = jnp.asarray(x), jnp.asarray(v), jnp.asarray(dt)
        v = consistent_velocity(v, x - state.x_prev, dt)
        d = jnp.sign(v)
        moving = d != 0
        reversal = moving & (state.last_d != 0) & (d != state.last_d)
        last_d = jnp.where(moving, d, state.last_d)
        s = self.stribeck.effective(v, last_d)
        s_r = self.stribeck.rest(state.last_d)
        stack = self._events(state.stack, x, s, reversal, state.x_prev, s_r)
        f_h, _, gamma = self._branch(x, s, *stack.top_entry())
        a, b = self._lag_coefficients(dt, s, d, state.last_d, reversal, state.s_prev, gamma)
        lag = a * state.lag + b
        new_state = TwoStateState(stack=stack, lag=lag, last_d=last_d, x_prev=x, s_prev=s)
        return new_state, f_h + lag + self.sigma2 * v

    # ---- whole trajectory -------------------------------------------------------------

    def _simulate(self, motion: Motion) -> SimResult:
        if type(self) is TwoState and _forward_kernel.supported(self, motion.t, motion.x, motion.v):
            force, parts, overflow = _forward_kernel.simulate(  # compiled, on the CPU
                self, motion.t, motion.x, motion.v, motion.max_reversals)
            return SimResult(force=force, parts=parts, overflow=overflow)
        return self._simulate_jax(motion.consistent())

    def _simulate_jax(self, motion: Motion) -> SimResult:
        """`_simulate` of a consistent `motion` in JAX (the path on GPU/TPU, and the JVP
        rule of the compiled forward pass, `jaxfric._kernel.forward`)."""
        s, rec = self._stage_events(motion)
        active, depth, popped_until = _fill_records(rec)
        h_e = self._stage_branch_starts(motion, rec, popped_until)
        x_e, s_e = self._entry(motion, active)
        f_h, _, gamma = self._branch(motion.x, s, x_e, h_e, s_e)
        lag = self._stage_lag(motion, s, gamma)
        viscous = self.sigma2 * motion.v
        # A bound below the true count (only if given by hand) would drop reversals: NaN.
        limit = motion.x.shape[0] if motion.max_reversals is None else motion.max_reversals
        count = jnp.sum(motion.reversal).astype(jnp.int32)
        fits = count <= limit
        f_h = jnp.where(fits, f_h, jnp.nan)
        lag = jnp.where(fits, lag, jnp.nan)
        # ... and is counted, also under jit/vmap: the reversals beyond the bound.
        dropped = jnp.where(fits, 0, count - limit).astype(rec.overflow.dtype)
        return SimResult(
            force=f_h + lag + viscous,
            parts={"hysteresis": f_h, "lag": lag, "viscous": viscous, "depth": depth},
            overflow=rec.overflow + dropped,
        )

    # The stages of `_simulate`, also timed one by one by
    # benchmarks/profiling/profile_two_state.py.

    def _stage_events(self, motion: Motion) -> tuple[Array, "_Events"]:
        """The Stribeck values ``S`` of every sample and the records of the event pass."""
        s = self.stribeck.effective(motion.v, motion.last_d)
        s_r = self.stribeck.rest(motion.prev_last_d)
        return s, self._event_pass(motion.x, s, motion.reversal, motion.x_prev, s_r)

    def _entry(self, motion: Motion, ref):
        """(x, s) of the entries pushed at samples `ref` (-1: the zero state). Their ``s``
        is the rest value ``rest(prev_last_d)`` of the reversal, taken as a direction
        times Fs rather than gathered from an array of rest values: under ``jacfwd`` a
        float gather carries every tangent."""
        r = jnp.maximum(ref, 0)
        return (
            jnp.where(ref >= 0, motion.x_prev[r], motion.x[0]),
            self.stribeck.rest(jnp.where(ref >= 0, motion.prev_last_d[r], 0.0)),
        )

    def _stage_branch_starts(self, motion: Motion, rec: "_Events", popped_until) -> Array:
        """``h`` of the entry each sample uses: F_h at the start of its branch (N).

        h of the entry pushed at reversal r is h(parent) + g_r (see `_push`); h of the
        entry in use is then the sum of g over the entries pushed so far minus those
        popped (entries dropped by wiping or overflow stay in: they are ancestors of the
        bottom). g is evaluated on the list of reversals only (`max_reversals` slots, a
        static bound; at most n), not on every sample.
        """
        n = motion.x.shape[0]
        reversal = motion.reversal
        limit = n if motion.max_reversals is None else motion.max_reversals
        size = max(1, min(limit, n))
        rank = running_sum(reversal.astype(jnp.int32))  # reversals at or before each sample
        # The samples of the reversals, in order: reversal k is the first sample whose rank
        # exceeds k (a binary search per slot rather than a scatter of n samples).
        k = jnp.arange(size, dtype=jnp.int32)
        rev = jnp.minimum(jnp.searchsorted(rank, k + 1, side="left"), n - 1).astype(jnp.int32)
        valid = k < rank[-1]
        x_p, s_p = self._entry(motion, rec.parent[rev])
        s_rev = self.stribeck.rest(motion.prev_last_d[rev])
        den = s_rev - s_p
        xi_rev = safe_div(motion.x_prev[rev] - x_p, den)
        g = jnp.where(valid, self.shape.pi(xi_rev, self.stribeck.Fs) * den, 0.0)
        # The popped list (sample indices of pushes, in order) holds at most one entry
        # per reversal; a push's place in the list of reversals is its rank - 1.
        popped = rec.popped[:size]
        g_popped = jnp.where(popped >= 0, g[jnp.maximum(rank[jnp.maximum(popped, 0)] - 1, 0)],
                             0.0)
        g_sum, g_popped_sum = running_sum(g), running_sum(g_popped)
        return jnp.where(rank > 0, g_sum[jnp.maximum(rank - 1, 0)], 0.0) - jnp.where(
            popped_until > 0, g_popped_sum[jnp.maximum(popped_until - 1, 0)], 0.0
        )

    def _stage_lag(self, motion: Motion, s, gamma) -> Array:
        """F_l (N) from its linear recurrence (`_lag_coefficients`)."""
        s_prev = jnp.concatenate([jnp.zeros_like(s[:1]), s[:-1]])
        a, b = self._lag_coefficients(
            motion.dt, s, motion.d, motion.prev_last_d, motion.reversal, s_prev, gamma
        )
        return linear_recurrence(a, b)


def _fill_records(rec: "_Events"):
    """Forward-fill the event records: each sample uses the state after the last event at
    or before it (the zero state before the first). Returns the entry in use (`active`,
    a sample index or -1), the stack `depth` and `popped_until` per sample (given by the
    kernel, which fills them as it goes)."""
    if rec.filled is not None:
        return rec.filled[:, 0], rec.filled[:, 1], rec.filled[:, 2]
    n = rec.table.shape[0] - 1
    idx = jnp.arange(n, dtype=jnp.int32)
    last = running_max(jnp.where(rec.event, idx, -1))
    seen = last >= 0
    last = jnp.maximum(last, 0)
    # Before any event: the zero state (-1), depth 1, no parent, nothing popped.
    none = jnp.array([-1, 1, -1, 0], jnp.int32)
    filled = jnp.where(seen[:, None], rec.table[last], none)
    return filled[:, 0], filled[:, 1], filled[:, 3]


#: Samples tested at once per iteration of the event loop (see `_event_loop`). Tried
#: and not kept: blocks of 512 made the event pass alone faster on smooth motions but the
#: whole simulation not measurably (XLA overlaps the loop with the rest), and motions
#: with a reversal every few samples (noisy measured velocities) slower, as every event
#: iteration tests the whole block; batches showed no difference either way.
_WINDOW = 64


def _apply_event(model, stack, hit, j, x, s, reversal, x_prev, s_r):
    """The event at sample `j` of one trajectory, if `hit`: `_push` at a reversal, then
    the `_close` cascade. Returns the new stack, the entry that was on top (the parent of
    a pushed one), the entries popped (``size`` slots, the first `count` valid), `count`."""
    size = stack.x.shape[0]

    def apply(stack):
        parent = stack.ref[stack.top]
        pushed = jax.lax.cond(
            reversal[j],
            lambda st: model._push(st, True, x_prev[j], s_r[j], j, with_h=False),
            lambda st: st,
            stack,
        )
        closed = model._close(pushed, x[j], s[j])
        # Popped: logical levels closed.depth .. pushed.depth - 1 (a run from the top).
        levels = closed.depth + jnp.arange(size, dtype=jnp.int32)
        refs = pushed.ref[(pushed.base + levels) % size]
        return closed, parent, refs, pushed.depth - closed.depth

    def skip(stack):
        return stack, jnp.int32(-1), jnp.full((size,), -1, jnp.int32), jnp.int32(0)

    return jax.lax.cond(hit, apply, skip, stack)


def _record(rec, hit, j, stack, parent, refs, npop, count):
    """Write one trajectory's event at sample `j` into its records (slot n if not `hit`)."""
    n = rec.table.shape[0] - 1
    row = jnp.stack([stack.ref[stack.top], stack.depth, parent, npop + count])
    return _Events(
        table=jax.lax.dynamic_update_slice(
            rec.table, row[None], (jnp.where(hit, j, n).astype(jnp.int32), jnp.int32(0))
        ),
        popped=jax.lax.dynamic_update_slice(rec.popped, refs, (npop,)),
        overflow=stack.overflow,
    )


def _event_loop(static, params, params_axes, X, S, R, XP, SR, batched=True):
    """The events of a batch of trajectories (leading axis of X, S, R, XP, SR; `params`
    batched where `params_axes` says 0), in one ``lax.while_loop`` over blocks of
    `_WINDOW` samples shared by the whole batch. With ``batched=False``, one trajectory
    (1-D arrays): the same loop without ``vmap``, so that an iteration without an event
    skips `_apply_event` (under ``vmap`` its ``lax.cond`` becomes a select).

    One iteration tests every sample of the current block at once, for every trajectory,
    against its current stack (a reversal, or a position that closes the top level), from
    the trajectory's next unprocessed sample on. Each trajectory with an event there
    applies its first one (`_apply_event`) and records it; the loop moves to the next block
    when no trajectory has an event left in this one. So a block costs one iteration plus
    one per event (of its busiest trajectory), and because the block start is the same for
    the whole batch, the windows are plain slices. The loop condition does not depend on
    the data, so nothing is selected wholesale under ``vmap`` (this function is what the
    ``vmap`` rule of `_event_records` calls).
    """
    *lead, n = X.shape
    lead = tuple(lead)
    size, W = static.stack_size, _WINDOW
    blocks = -(-n // W)

    def pad(a):
        return jnp.concatenate([a, jnp.zeros((*lead, blocks * W - n), a.dtype)], axis=-1)

    Xw, Sw, Rw = pad(X), pad(S), pad(R)
    records = _Events(
        table=jnp.zeros((*lead, n + 1, 4), jnp.int32),
        popped=jnp.full((*lead, n + size), -1, jnp.int32),
        overflow=jnp.zeros(lead, jnp.int32),
    )
    zero_state = functools.partial(MemoryStack.zero_state, size)
    stack0 = jax.vmap(zero_state)(X[:, 0]) if batched else zero_state(X[0])
    zeros = jnp.zeros(lead, jnp.int32)
    offsets = jnp.arange(W, dtype=jnp.int32)

    def one(params, stack, nxt, npop, rec, xs, ss, rs, x, s, r, xp, sr, start):
        model = eqx.combine(params, static)
        sample = start + offsets
        ev = (rs | model._top_closes(stack, xs, ss)) & (sample >= nxt) & (sample < n)
        k = jnp.argmax(ev).astype(jnp.int32)
        hit = ev[k]
        j = jnp.minimum(start + k, n - 1)
        stack, parent, refs, count = _apply_event(model, stack, hit, j, x, s, r, xp, sr)
        rec = _record(rec, hit, j, stack, parent, refs, npop, count)
        return stack, jnp.where(hit, j + 1, nxt), npop + count, rec, hit

    step = jax.vmap(one, in_axes=(params_axes, *[0] * 12, None)) if batched else one

    def body(carry):
        block, stack, nxt, npop, rec = carry
        start = block * W
        window = [jax.lax.dynamic_slice_in_dim(a, start, W, axis=-1) for a in (Xw, Sw, Rw)]
        stack, nxt, npop, rec, hit = step(
            params, stack, nxt, npop, rec, *window, X, S, R, XP, SR, start
        )
        return jnp.where(jnp.any(hit), block, block + 1), stack, nxt, npop, rec

    carry = (jnp.int32(0), stack0, zeros, zeros, records)
    return jax.lax.while_loop(lambda c: c[0] < blocks, body, carry)[4]


def _event_records(static):
    """For the non-array part `static` of a `TwoState`, a function of its array part and
    one trajectory that returns the records of its events (the sequential part of
    `TwoState._simulate`): a ``lax.while_loop`` that jumps from event to event, about
    ``n / window + number of events`` iterations instead of ``n``. Under ``vmap`` the
    whole batch runs in one loop (`_event_loop`)."""

    @jax.custom_batching.custom_vmap
    def records(params, x, s, reversal, x_prev, s_r):
        return _event_loop(static, params, None, x, s, reversal, x_prev, s_r, batched=False)

    @records.def_vmap
    def records_vmap(axis_size, in_batched, params, *arrays):
        params_batched, *arrays_batched = in_batched
        arrays = [
            a if b else jnp.broadcast_to(a, (axis_size, *a.shape))
            for a, b in zip(arrays, arrays_batched)
        ]
        params_axes = jax.tree.map(lambda b: 0 if b else None, params_batched)
        rec = _event_loop(static, params, params_axes, *arrays)
        return rec, jax.tree.map(lambda _: True, rec)

    return records


class _Events(eqx.Module):
    """Records of `TwoState._event_pass`. `table` has a row per sample (row ``n`` is
    scratch) and is written at event samples only, with: the entry in use after the event
    (`active`: a reversal's sample index, or -1 for the zero state), the stack `depth` (0:
    no event at this sample), the `parent` of the entry pushed there, and `popped_until`,
    the length of the list `popped` of entries closed so far (their sample indices, in
    order); `overflow` counts entries dropped for space. One table rather than an array per
    field because each write in the event loop is a separate kernel call on the CPU. The
    compiled kernel also returns `filled` (what `_fill_records` computes; None from the
    JAX loop)."""

    table: Int[Array, "n1 4"]
    popped: Int[Array, " m"]
    overflow: Int[Array, ""]
    filled: Int[Array, "n 3"] | None = None

    @property
    def event(self):
        return self.table[:-1, 1] > 0

    @property
    def active(self):
        return self.table[:-1, 0]

    @property
    def depth(self):
        return self.table[:-1, 1]

    @property
    def parent(self):
        return self.table[:-1, 2]

    @property
    def popped_until(self):
        return self.table[:-1, 3]
