"""Export a LuGre model to MuJoCo (`to_mujoco`): an MJCF with one joint and a passive
``dcmotor`` actuator (``input="none"``, MuJoCo 3.7 and later) carrying the fitted values.

MuJoCo's ``dcmotor`` has LuGre friction (``lugre = "stiffness damping coulomb static
stribeck"``, with a Stribeck exponent of 2), cogging (``cogging = "amplitude poles phase"``,
a torque ``amplitude*sin(poles*q + phase)``) and the actuator's viscous ``damping``. So it
represents a jaxfric `LuGre` model, plus the `viscous` and `cogging` effects, and nothing
else: other models and effects are refused with the reason, and the closest LuGre fit
offered (``jaxfric fit FILE --model lugre``). A fitted Stribeck exponent other than 2 is
replaced by 2, and the MJCF says so in a comment.

Signs: jaxfric's friction force points along the motion (the force the drive supplies);
MuJoCo's actuator applies the opposite, so the joint feels ``-F``: ``actuator_force`` holds
the LuGre and cogging part and ``qfrc_damper`` the viscous part. Units: a ``slide`` joint
takes the model as it is (m, N); a ``hinge`` joint reads its numbers as rad and N m.
"""

import math
from pathlib import Path

from .._atomic import write_text
from .._models.lugre import LuGre
from ..effects import Cogging, Viscous, WithEffects
from ._parts import ExportError


_REFIT = "fit the closest LuGre model with 'jaxfric fit FILE --model lugre' and export that"


def _split(model):
    base, effects = (model.base, model.effects) if isinstance(model, WithEffects) else (model, ())
    if not isinstance(base, LuGre):
        raise ExportError(f"MuJoCo's dcmotor actuator represents LuGre friction only; the "
                          f"{type(base).__name__} model cannot be represented: {_REFIT}")
    bad = [e.name for e in effects if not isinstance(e, Viscous | Cogging)]
    if bad:
        raise ExportError(f"MuJoCo's dcmotor actuator cannot represent the effect(s) "
                          f"{', '.join(bad)} (it has LuGre friction, viscous damping and "
                          f"cogging only): {_REFIT} without them")
    return base, effects


def _num(v) -> str:
    return repr(float(v))


def approximations(model) -> list[str]:
    """What `mjcf` changes in `model` because MuJoCo cannot represent it (one sentence
    each; empty when nothing). Raises `ExportError` for what it cannot represent at all."""
    base, _ = _split(model)
    delta = float(base.stribeck.delta)
    if abs(delta - 2.0) > 1e-12:
        return [f"the fitted Stribeck exponent delta = {delta:.6g} is replaced by MuJoCo's "
                "fixed exponent 2"]
    return []


def mjcf(model, joint: str = "slide", timestep: float = 1e-3,
         comment: str | None = None) -> str:
    """The MJCF text for `model` (a `LuGre`, optionally with `viscous` and `cogging`
    effects) on one `joint` (``"slide"`` or ``"hinge"``), simulated with `timestep` (s);
    `comment` (lines of text, such as the fit's status and standard errors) is added to
    its opening comment. What it approximates is said there too (`approximations`).
    Raises `ExportError` for what MuJoCo cannot represent."""
    if joint not in ("slide", "hinge"):
        raise ExportError(f"joint must be 'slide' or 'hinge', got {joint!r}")
    base, effects = _split(model)
    st = base.stribeck
    damping = float(base.sigma2) + sum(float(e.c_visc) for e in effects
                                       if isinstance(e, Viscous))
    notes = approximations(model)
    extra = "".join(f"\n       {line}" for line in
                    (comment or "").replace("--", "- -").splitlines())
    attrs = [f'lugre="{_num(base.sigma0)} {_num(base.sigma1)} {_num(st.Fc)} {_num(st.Fs)} '
             f'{_num(st.Vs)}"', f'damping="{_num(damping)}"']
    for e in effects:
        if isinstance(e, Cogging):
            # cog_sin*sin(w q) + cog_cos*cos(w q) = -A*sin(w q + phase): MuJoCo's sign.
            amp = math.hypot(float(e.cog_sin), float(e.cog_cos))
            phase = math.atan2(-float(e.cog_cos), -float(e.cog_sin))
            attrs.append(f'cogging="{_num(amp)} {_num(2 * math.pi / float(e.period))} '
                         f'{_num(phase)}"')
    unit, force = ("m", "N") if joint == "slide" else ("rad", "N m")
    note = ("approximated: " + "; ".join(notes)) if notes else "nothing approximated"
    axis = "1 0 0" if joint == "slide" else "0 0 1"
    return f"""\
<mujoco model="jaxfric friction">
  <!-- Exported by jaxfric from {type(base).__name__}{' + ' + ', '.join(e.name for e in effects)
                                                    if effects else ''}: LuGre friction
       sigma0 = {_num(base.sigma0)} {force}/{unit}, sigma1 = {_num(base.sigma1)} {force} s/{unit},
       Fc = {_num(st.Fc)} {force}, Fs = {_num(st.Fs)} {force}, Vs = {_num(st.Vs)} {unit}/s,
       viscous damping {_num(damping)} {force} s/{unit} (sigma2 plus the viscous effect).
       {note}.
       The actuator is passive (input="none", motorconst 0: no electrical branch); the joint
       feels minus jaxfric's friction force (actuator_force + qfrc_damper).{extra} -->
  <option timestep="{_num(timestep)}"/>
  <worldbody>
    <body name="axis">
      <joint name="axis" type="{joint}" axis="{axis}"/>
      <geom type="box" size="0.05 0.05 0.05" mass="1"/>
    </body>
  </worldbody>
  <actuator>
    <dcmotor name="friction" joint="axis" input="none" motorconst="0 0" resistance="1"
             {' '.join(attrs)}/>
  </actuator>
</mujoco>
"""


def to_mujoco(model, path, joint: str = "slide", timestep: float = 1e-3) -> Path:
    """Write `mjcf` for `model` (or a saved model / fit or diagnosis JSON path) to `path`."""
    if isinstance(model, str | Path):
        from .._serialize import load_model

        model = load_model(model)
    text = mjcf(model, joint, timestep)
    return write_text(path, text)
