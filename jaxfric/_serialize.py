"""Models as JSON: every field of every part, exactly, so a saved model is the same model.

`model_to_dict` writes a model (any friction model, with its Stribeck curve, shape and
effects) as nested plain data: each module is ``{"class": name, field: value, ...}``,
parameters as numbers (or lists of numbers for vector parameters such as GMS weights),
static fields (``stack_size``, a position effect's travel) as they are. Python's ``float``
text is the shortest one that reads back to the same float64, so `model_from_dict` rebuilds
the model to the bit. Non-finite values are refused: RFC 8259 JSON has no NaN or Infinity.

Classes are found by name among the subclasses of the jaxfric base classes (models,
shapes, effects) and the Stribeck curve, so a shape or effect defined elsewhere (e.g. in
`fitting`) loads once its module is imported.
"""

import dataclasses
import json
import math
from pathlib import Path
from typing import Any

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ._atomic import write_text
from ._models._base import AbstractFrictionModel
from ._shapes import AbstractShape
from ._stribeck import Stribeck


FORMAT = "jaxfric-model/1"


def _classes() -> dict[str, type]:
    from .effects import AbstractEffect, WithEffects

    found = {"Stribeck": Stribeck, "WithEffects": WithEffects}
    todo = [AbstractFrictionModel, AbstractShape, AbstractEffect]
    while todo:
        cls = todo.pop()
        for sub in cls.__subclasses__():
            found.setdefault(sub.__name__, sub)
            todo.append(sub)
    return found


def _value(x, where: str):
    if isinstance(x, eqx.Module):
        return model_to_dict(x, where)
    if isinstance(x, tuple | list):
        return [_value(e, f"{where}[{i}]") for i, e in enumerate(x)]
    if isinstance(x, bool | int | str) or x is None:
        return x
    arr = np.asarray(x)
    if not np.issubdtype(arr.dtype, np.number):
        raise TypeError(f"{where}: cannot save a {type(x).__name__}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{where} is not finite ({arr.tolist()}): JSON has no NaN or Infinity")
    if np.issubdtype(arr.dtype, np.integer):
        return arr.tolist()
    return arr.astype(np.float64).tolist()


def model_to_dict(model: eqx.Module, where: str = "model") -> dict[str, Any]:
    """`model` as nested plain data (see the module docstring)."""
    out: dict[str, Any] = {"class": type(model).__name__}
    for f in dataclasses.fields(model):
        out[f.name] = _value(getattr(model, f.name), f"{where}.{f.name}")
    return out


def _build(spec, classes, where: str):
    if isinstance(spec, dict) and "class" in spec:
        name = spec["class"]
        cls = classes.get(name)
        if cls is None:
            raise ValueError(f"{where}: unknown class {name!r} (known: {sorted(classes)})")
        fields = {f.name: f for f in dataclasses.fields(cls)}
        unknown = set(spec) - set(fields) - {"class"}
        if unknown:
            raise ValueError(f"{where}: {name} has no field(s) {sorted(unknown)}")
        kwargs = {}
        for key, value in spec.items():
            if key == "class":
                continue
            built = _build(value, classes, f"{where}.{key}")
            if isinstance(built, list) and not fields[key].metadata.get("static", False) and (
                    all(isinstance(v, int | float) for v in built)):
                built = jnp.asarray(built, dtype=jnp.float64)
            kwargs[key] = built
        if cls.__name__ == "WithEffects":
            kwargs["effects"] = tuple(kwargs["effects"])
        return cls(**kwargs)
    if isinstance(spec, list):
        return [_build(v, classes, f"{where}[{i}]") for i, v in enumerate(spec)]
    if isinstance(spec, float) and not math.isfinite(spec):
        raise ValueError(f"{where} is not finite")
    return spec


def model_from_dict(spec: dict[str, Any]) -> AbstractFrictionModel:
    """Inverse of `model_to_dict`: the model, with float64 parameters."""
    if not isinstance(spec, dict) or "class" not in spec:
        raise ValueError("a saved model is a JSON object with a 'class' entry")
    return _build(spec, _classes(), "model")


def save_model(model: AbstractFrictionModel, path) -> None:
    """Write `model` as JSON (``{"format": ..., "model": model_to_dict(model)}``) to
    `path`."""
    text = json.dumps({"format": FORMAT, "model": model_to_dict(model)}, indent=2,
                      allow_nan=False)
    write_text(path, text + "\n")


def load_model(source) -> AbstractFrictionModel:
    """The model saved in `source`: a path or an already parsed JSON object, holding a saved
    model (`save_model`), or a fit or diagnosis result of the ``jaxfric`` command
    (their ``"fitted_model"`` entry)."""
    if isinstance(source, str | Path):
        source = json.loads(Path(source).read_text())
    if not isinstance(source, dict):
        raise ValueError(f"expected a JSON object, got a {type(source).__name__}")
    for key in ("fitted_model", "model"):
        if isinstance(source.get(key), dict):
            return model_from_dict(source[key])
    if "class" in source:
        return model_from_dict(source)
    raise ValueError("no saved model in this JSON (expected a 'model' or 'fitted_model' "
                     "object, as written by jaxfric.save_model or 'jaxfric fit --json')")
