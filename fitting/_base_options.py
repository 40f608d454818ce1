"""The other base models a diagnosis tries instead of the fitted one (docs/diagnosis.md,
"The candidates"): a GMS with `GMS_ELEMENTS` elements (a richer presliding curve), a LuGre
model (another family: a rate-dependent bristle), and the starts they are fitted from.
When one is added, the base model was the limit, not a missing effect."""

from jaxfric import LuGre

from ._candidates import Data
from ._refits import _replaced
from ._select import _base_starts
from ._start import gms_like, initial_model, lag_starts


#: The elements of the richer base model a diagnosis tries (`_richer`).
GMS_ELEMENTS = 20


def _richer(fallback):
    """A start of the GMS option, as a function of the fitted plain model: a GMS with
    `GMS_ELEMENTS` elements started where a fitted two-state model is
    (`fitting._start.gms_like`: its presliding curve, Stribeck curve and lag), so its
    refit starts where the fit is (and in the fit's optimum); for another family,
    `fallback` (`_from_data`: read off the longest run)."""

    def make(plain):
        gms = gms_like(plain, GMS_ELEMENTS)
        return gms if gms is not None else fallback(plain)

    return make


def _read_off(longest: Data, family: str, **options):
    """A start made once, whatever the fit is: `initial_model` of `family` read off the
    longest run."""
    made = []

    def make(_plain):
        if not made:
            made.append(initial_model(family, longest.t, longest.x, longest.F, longest.v,
                                      **options))
        return made[0]

    return make


def _from_data(longest: Data):
    """A start of the GMS option: a GMS with `GMS_ELEMENTS` elements read off the longest
    run (`_read_off`), whatever the fit is. A two-state fit in a poor
    optimum (a frozen lag, a step-like Stribeck curve) hands that optimum to `gms_like`;
    on point-to-point moves of a 60-element GMS truth the GMS refit from it ends at
    1.43 N RMS, from the data at 0.26 N (noise 0.1 N)."""
    return _read_off(longest, "gms", n_elements=GMS_ELEMENTS)


class _FastLag:
    """A start of the GMS option: `make`'s with the fast lag (`lag_starts`, as the base
    fit's race; `make`'s itself where its lag is as fast or ``C`` is `fixed`). Read off the
    data a GMS's lag is set by crude simulations, and from a slow one the fit can settle
    where the lag is a memory of the motion: on a jerk-limited stiction file with a mass
    and cogging, 1.72 N RMS, from the fast lag 0.63 N."""

    def __init__(self, make, fixed):
        self.make, self.fixed = make, tuple(fixed)

    def __call__(self, plain):
        return lag_starts(self.make(plain), self.fixed)[-1][1]


def default_base_models(model, longest: Data, fixed=()) -> list[tuple[str, tuple]]:
    """The base-model options a diagnosis of `model` tries by default, ``[(name, starts)]``:
    a GMS with `GMS_ELEMENTS` elements, its starts ``(label, maker)`` read off the data
    (`_from_data`), that with the fast lag (`_FastLag`) and, when that start exists (a
    two-state model), at the fit (`_richer`); and a LuGre model read off the data
    (`_read_off`), unless `model` is one. The rule keeps each option's best training
    fit (`fitting._select`)."""
    data = _from_data(longest)  # one start read off the data, made once, for all
    starts = (("read off the data", data), ("read off the data, fast lag",
                                            _FastLag(data, fixed)))
    if gms_like(model.without_effects(), GMS_ELEMENTS) is not None:
        starts += (("started at the fit", _richer(data)),)
    options = [(f"GMS with {GMS_ELEMENTS} elements", starts)]
    if not isinstance(model.without_effects(), LuGre):
        options.append(("LuGre", (("read off the data", _read_off(longest, "lugre")),)))
    return options


def base_model_starts(base_models, fit) -> list[tuple[str, object]]:
    """``[(name (label), model)]``: every start of the base models `base_models`
    (`default_base_models`' form) made from `fit`, with its effects; the models the search
    copy must carry (`_search_copy`). Not a fast-lag start (`_FastLag`): like the base
    fit's own (the copy carries its race's winner), it is where a fit begins, not a model
    the search compares; checked with it, the copy of a 1e5-sample record (the one of
    `benchmarks/diagnose_speed.py`) grew from 9.7e3 to 3.4e4 samples."""
    return [(f"{name} ({label})", _replaced(start, fit)) for name, starts in base_models
            for label, make, start in _base_starts(starts, None, fit.without_effects())
            if not isinstance(make, _FastLag)]
