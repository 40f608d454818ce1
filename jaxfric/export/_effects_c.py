"""C translations of the effects of `jaxfric.effects` (`WithEffects.step`): each returns a
`Part` whose step statements add the effect's term to ``total``. In scope: ``t`` (s),
``x`` (m), ``v`` (m/s), ``dt`` (s), ``dx`` (m), ``a`` (m/s^2, the backward difference of
``v``, 0 at the first sample), ``f`` (the base model's force, N), ``stat`` (its Stribeck
curve ``s(v)``, N) and ``load`` (the transmitted load, N or N m: the argument of
``jaxfric_step_load``). Effects without a translation are refused by name. `reads_load`
says whether a model has an effect that reads the load (`jaxfric.effects.LOAD_EFFECTS`):
its export then has only ``jaxfric_step_load``, so that the load cannot be forgotten."""

import numpy as np

from .. import effects as fx
from ._parts import const, ExportError, Part


def _c(effect, name: str) -> tuple[str, float, str]:
    return const(effect, name, f"JF_{name.upper()}", f"effect {effect.name}")


def _travel(effect) -> list[tuple[str, float, str]]:
    key = effect.name.upper()
    return [(f"JF_{key}_X_MID", float(effect.x_mid), f"effect {effect.name}.x_mid [m]"),
            (f"JF_{key}_X_HALF", float(effect.x_half), f"effect {effect.name}.x_half [m]")]


def _u(effect) -> str:
    key = effect.name.upper()
    return f"(x - JF_{key}_X_MID) / JF_{key}_X_HALF"


def _viscous(e):
    return Part(consts=[_c(e, "c_visc")], step="    total += JF_C_VISC * v;\n")


def _drag(e):
    return Part(consts=[_c(e, "c_drag")], step="    total += JF_C_DRAG * v * fabs(v);\n")


def _hump(e):
    return Part(consts=[_c(e, "dF_str"), _c(e, "v_str")], step=(
        "    { double r = jf_div(v, JF_V_STR);\n"
        "      total += JF_DF_STR * exp(-(r * r)) * jf_sign(v); }\n"))


def _inertia(e):
    return Part(consts=[_c(e, "mass")], step="    total += JF_MASS * a;\n")


def _offset(e):
    return Part(consts=[_c(e, "offset")], step="    total += JF_OFFSET;\n")


def _asymmetry(e):
    return Part(consts=[_c(e, "asym")], step="    total += JF_ASYM * fabs(f);\n")


def _cogging(e):
    return Part(consts=[_c(e, "cog_sin"), _c(e, "cog_cos"), _c(e, "period")], step=(
        "    { double ph = 2.0 * 3.141592653589793 * jf_div(x, JF_PERIOD);\n"
        "      total += JF_COG_SIN * sin(ph) + JF_COG_COS * cos(ph); }\n"))


def _ripple(e):
    consts = [const(e, "period", "JF_RIP_PERIOD", "effect ripple")]  # cogging has JF_PERIOD
    lines = []
    for k, (a, b) in enumerate(zip(np.asarray(e.rip_sin, float), np.asarray(e.rip_cos, float))):
        consts += [(f"JF_RIP_SIN_{k + 1}", float(a), f"effect ripple.rip_sin[{k}] [N]"),
                   (f"JF_RIP_COS_{k + 1}", float(b), f"effect ripple.rip_cos[{k}] [N]")]
        lines.append(f"      total += JF_RIP_SIN_{k + 1} * sin({k + 1}.0 * ph)"
                     f" + JF_RIP_COS_{k + 1} * cos({k + 1}.0 * ph);\n")
    return Part(consts=consts, step=(
        "    { double ph = 2.0 * 3.141592653589793 * jf_div(x, JF_RIP_PERIOD);\n"
        + "".join(lines) + "    }\n"))


def _angle_load(e):
    return Part(consts=[_c(e, "g_sin"), _c(e, "g_cos")],
                step="    total += JF_G_SIN * sin(x) + JF_G_COS * cos(x);\n")


def _position_dependence(e):
    return Part(consts=[_c(e, "pos_1"), _c(e, "pos_2"), *_travel(e)], step=(
        f"    {{ double u = {_u(e)};\n"
        "      total += f * (JF_POS_1 * u + JF_POS_2 * (u * u)); }\n"))


def _position_load(e):
    return Part(consts=[_c(e, "load_1"), _c(e, "load_2"), *_travel(e)], step=(
        f"    {{ double u = {_u(e)};\n"
        "      total += JF_LOAD_1 * u + JF_LOAD_2 * (u * u - 1.0 / 3.0); }\n"))


def _drift(e):
    return Part(consts=[_c(e, "drift_rate"), _c(e, "drift_decay"), _c(e, "drift_level")],
                step=(
        "    { double el = t - s->t0, u = JF_DRIFT_DECAY * el;\n"
        "      double phi = fabs(u) < 1e-4 ? 1.0 - u / 2.0 + u * u / 6.0 : -expm1(-u) / u;\n"
        "      total += f * (JF_DRIFT_LEVEL + JF_DRIFT_RATE * el * phi); }\n"))


def _presliding(e):
    return Part(
        consts=[_c(e, "F_pre"), _c(e, "k_pre")],
        fields=["double pre_h; /* presliding effect: elasto-plastic element force [N] */"],
        init="    s->pre_h = 0.0;\n",
        step=("    { double h = s->pre_h + JF_K_PRE * dx;\n"
              "      s->pre_h = h < -JF_F_PRE ? -JF_F_PRE : (h > JF_F_PRE ? JF_F_PRE : h);\n"
              "      total += s->pre_h - JF_F_PRE * jf_sign(v); }\n"))


def _load_friction(e):
    return Part(consts=[_c(e, "k_load")], step=(
        "    { double d = jf_div(f, fabs(stat));\n"
        "      d = d < -1.0 ? -1.0 : (d > 1.0 ? 1.0 : d);\n"
        "      total += JF_K_LOAD * fabs(load) * d; }\n"))


def _friction_lag(e):
    return Part(
        consts=[_c(e, "lag_gain"), _c(e, "tau")],
        fields=["double lag_y; /* friction_lag effect: the lagged level [N] */",
                "int lag_started; /* friction_lag effect: moved at least once */"],
        init="    s->lag_y = 0.0;\n    s->lag_started = 0;\n",
        step=("    { double level = fabs(stat), g;\n"
              "      int moving = v != 0.0;\n"
              "      g = moving ? (s->lag_started ? exp(-jf_div(dt, JF_TAU)) : 0.0) : 1.0;\n"
              "      s->lag_y = g * s->lag_y + (1.0 - g) * level;\n"
              "      s->lag_started = s->lag_started || moving;\n"
              "      total += JF_LAG_GAIN * jf_sign(stat) * (s->lag_y - level); }\n"))


_TRANSLATORS = {
    fx.Viscous: _viscous, fx.QuadraticDrag: _drag, fx.StribeckHump: _hump,
    fx.Inertia: _inertia, fx.Offset: _offset, fx.Asymmetry: _asymmetry, fx.Cogging: _cogging,
    fx.PositionDependence: _position_dependence, fx.PositionLoad: _position_load,
    fx.Drift: _drift, fx.Presliding: _presliding, fx.FrictionLag: _friction_lag,
    fx.Ripple: _ripple, fx.AngleLoad: _angle_load, fx.LoadFriction: _load_friction,
}

#: Names of the effects the C export translates.
EXPORTABLE = tuple(sorted(cls.name for cls in _TRANSLATORS))


def reads_load(effects) -> bool:
    """Whether one of `effects` reads the load signal (`jaxfric.effects.LOAD_EFFECTS`)."""
    return any(getattr(e, "name", None) in fx.LOAD_EFFECTS for e in effects)


def effect_part(effect) -> Part:
    """The `Part` adding `effect`'s term to ``total``; `ExportError` if it has none."""
    translate = _TRANSLATORS.get(type(effect))
    if translate is None and hasattr(effect, "of_run"):  # `fitting._per_run._PerRunEffect`
        raise ExportError(
            f"the effect '{effect.name}' has one value per run (a fit to several runs): "
            "export one run's model, fitting.run_model(model, i), or the model for a run not "
            "fitted, fitting.run_model(model, None) (per-run values at their mean; what "
            "`jaxfric export` writes from a result's JSON)")
    if translate is None:
        name = getattr(effect, "name", type(effect).__name__)
        raise ExportError(f"the effect '{name}' ({type(effect).__name__}) cannot be exported "
                          f"to C: no causal per-sample translation (exportable effects: "
                          f"{', '.join(EXPORTABLE)})")
    return translate(effect)
