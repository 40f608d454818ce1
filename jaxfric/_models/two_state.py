"""The two-state GMS-based model (paper Sec. 4; docs/algorithm.md section 4).

Structure, chosen for speed and clean gradients:

* the event logic (reversal detection, stack push with wiping-out and overflow, the
  loop-closure cascade) is the only sequential part: one small ``lax.scan`` whose carry is
  the fixed-size memory stack and whose output is the reference entry in use at each sample;
* ``F_h`` is algebraic given that entry (Eq. 32), so it is computed vectorised afterwards;
* ``F_l`` is a linear recurrence (exact decay), computed with an associative scan.

``TwoState.step`` composes the very same helpers for one sample, for closed-loop use.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Bool, Float, Int

from .._inputs import Motion
from .._numerics import as_param, linear_recurrence, safe_div
from .._shapes import AbstractShape
from .._stribeck import Stribeck
from ._base import AbstractFrictionModel, SimResult


class MemoryStack(eqx.Module):
    """Reversal points in fixed-size arrays used as a circular buffer.

    Logical entry ``i`` (0 = bottom, ``depth - 1`` = top) lives in slot ``(base + i) % K``.
    Wiping-out and overflow only move `base`, and a push writes one slot, so the per-sample
    cost does not grow with ``K`` except for the vectorised loop-closure test.

    Per entry: `x` (m), `h` = F_h at the start of the branch (N), `s` = the Stribeck rest
    value at the reversal (N; 0 for the zero state), `theta` = its presliding extent
    ``|x - x_below| / |s - s_below|`` (m/N), `closable` = ``theta <= l1`` (Eq. 25/29).
    `zero_bottom` says whether the bottom entry is the zero state; `overflow` counts the
    entries dropped because the buffer was full.
    """

    x: Float[Array, " K"]
    h: Float[Array, " K"]
    s: Float[Array, " K"]
    theta: Float[Array, " K"]
    closable: Bool[Array, " K"]
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
    sigma2: Array = eqx.field(converter=as_param)
    C: Array = eqx.field(converter=as_param)
    stack_size: int = eqx.field(static=True, default=16)

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

    def _push(self, stack: MemoryStack, reversal, x_r, s_r) -> MemoryStack:
        """Rule 1 at reversal point ``x_r`` (rest value ``s_r``), with wiping and overflow;
        nothing changes where `reversal` is false."""
        size = stack.x.shape[0]
        top = stack.top
        x_e, h_e, s_e = stack.top_entry()
        den = s_r - s_e
        # F_h at the reversal, in the v -> 0 limit s = s_r (MODEL_NOTES, traps).
        h_r = h_e + self.shape.pi(safe_div(x_r - x_e, den), self.stribeck.Fs) * den
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
        """Rule 1 (push) then Rules 2-3 (closures) for one sample.

        Both are rare, so an ordinary sample only pays for a few scalar tests: the push
        runs under ``lax.cond`` on `reversal`, and the K-wide closure cascade only when the
        top level closes (a cascade always starts there). Under ``vmap`` the conds become
        selects, and the per-sample cost is then shared by the whole batch.
        """
        stack = jax.lax.cond(
            reversal,
            lambda st: self._push(st, True, x_r, s_r),
            lambda st: st,
            stack,
        )
        top = stack.top
        x_e, s_e = stack.x[top], stack.s[top]
        # Same test as `_close` applies to the top level (level >= 1, closable, xi >= theta);
        # level 1 needs the zero state below it.
        top_closes = (
            (stack.depth >= 2)
            & stack.closable[top]
            & ((stack.depth >= 3) | stack.zero_bottom)
            & (safe_div(x - x_e, s - s_e) >= stack.theta[top])
        )
        return jax.lax.cond(top_closes, lambda st: self._close(st, x, s), lambda st: st, stack)

    def _lag_coefficients(self, dt, s, d, prev_last_d, reversal, s_prev, gamma):
        """``F_l,n = a * F_l,n-1 + b`` (docs/algorithm.md section 4, step 4)."""
        moving = d != 0
        decay = jnp.exp(-self.C * safe_div(dt, jnp.abs(s)))
        a = jnp.where(reversal, 0.0, jnp.where(moving, decay, 1.0))
        # After a reversal or at the first motion, s jumps across v = 0 at xi = 0, where
        # gamma = 0: the step starts from the rest value on the new side.
        start = jnp.where(moving & (d != prev_last_d), self.stribeck.rest(d), s_prev)
        b = -gamma * (s - start)
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
        s = self.stribeck.effective(motion.v, motion.last_d)
        s_r = self.stribeck.rest(motion.prev_last_d)
        reversal = motion.reversal

        def body(stack, inp):
            stack = self._events(stack, *inp)
            return stack, (*stack.top_entry(), stack.depth)

        stack0 = MemoryStack.zero_state(self.stack_size, motion.x[0])
        final, (x_e, h_e, s_e, depth) = jax.lax.scan(
            body, stack0, (motion.x, s, reversal, motion.x_prev, s_r)
        )
        f_h, _, gamma = self._branch(motion.x, s, x_e, h_e, s_e)
        s_prev = jnp.concatenate([jnp.zeros_like(s[:1]), s[:-1]])
        a, b = self._lag_coefficients(
            motion.dt, s, motion.d, motion.prev_last_d, reversal, s_prev, gamma
        )
        lag = linear_recurrence(a, b)
        viscous = self.sigma2 * motion.v
        return SimResult(
            force=f_h + lag + viscous,
            parts={"hysteresis": f_h, "lag": lag, "viscous": viscous, "depth": depth},
            overflow=final.overflow,
        )
