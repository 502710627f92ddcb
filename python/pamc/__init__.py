"""pamc from Python: the pneumatic-muscle model, its identification and diagnosis, the plant emulator
and the controllers, as thin bindings of the C++ library (docs/PYTHON.md)."""

from ._pamc import (Controller, Measurement, Model, Plant, Trajectory, closed_loop, experiments, read_csv,
                    write_csv)
from . import _pamc

__all__ = ["Controller", "Measurement", "Model", "Plant", "Trajectory", "closed_loop", "compare", "diagnose",
           "experiments", "fit", "read_csv", "write_csv"]


def _data(t, u=None, y=None, load=None, p=None):
    """A Measurement, or one made of the arrays t, u, y (and load, p when given)."""
    if isinstance(t, Measurement):
        if u is not None or y is not None:
            raise TypeError("give a Measurement or the arrays t, u, y, not both")
        return t
    if u is None or y is None:
        raise TypeError("t, u and y are needed (or a Measurement)")
    return Measurement(t, u, y, load=load, p=p)


def fit(t, u=None, y=None, *, effects=(), method="auto", load=None, seed=1, threads=0, output_form="aligned",
        start=None):
    """Identifies a model (the Bouc-Wen core plus `effects`) from a record, as `pamc fit` does.

    Returns (model, report): report is the dict a model file written by `pamc fit --out` keeps under "fit".
    method: "auto" (lm for the plain core, ga with effects), "lm" or "ga"."""
    return _pamc._fit(_data(t, u, y, load), list(effects), method, seed, threads, output_form, start)


def compare(model, t, u=None, y=None, *, load=None):
    """`pamc compare --json`'s dict for `model` on a record, plus the arrays t, y_model and residual (y - y_model)."""
    return _pamc._compare(model, _data(t, u, y, load))


def diagnose(t, u=None, y=None, *, load=None, validate=None, **settings):
    """`pamc diagnose --json`'s dict for a record, plus "final_model": the ladder's final model
    as a pamc.Model ("model" holds it as the JSON does).

    validate: a Measurement or a tuple (t, u, y[, load]); without it the last `holdout` of the record.
    settings: holdout, max_effects, min_gain, candidates, seed, threads, method ("lm", "ga"), probes,
    output_form."""
    val = None if validate is None else validate if isinstance(validate, Measurement) else _data(*validate)
    return _pamc._diagnose(_data(t, u, y, load), val, **settings)
