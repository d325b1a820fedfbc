"""Settings of an estimator, scikit-learn style: given to ``__init__``, kept as they were given.

:class:`ParamsMixin` reads a class's settings from its ``__init__`` signature, so a
calibrator names each setting once: ``get_params``, ``set_params``, the ``repr``, and the
settings a calibration file stores all follow from it.
"""

from __future__ import annotations

import inspect

import numpy as np

from ...exceptions import InputError

__all__ = ["ParamsMixin", "clone"]


def clone(estimator, **settings):
    """A new unfitted estimator of the same class and settings, with those of ``settings``
    that are settings of the class changed (scikit-learn's ``clone``)."""
    params = estimator.get_params()
    params.update({key: value for key, value in settings.items() if key in params})
    return type(estimator)(**params)


class ParamsMixin:
    """``get_params``/``set_params``/``repr`` from the ``__init__`` signature."""

    @classmethod
    def _param_names(cls) -> list[str]:
        signature = inspect.signature(cls.__init__)
        return [name for name in signature.parameters if name != "self"]

    def get_params(self) -> dict:
        """Settings given to ``__init__``."""
        return {name: getattr(self, name) for name in self._param_names()}

    def set_params(self, **params):
        """Change settings given to ``__init__``; returns self (scikit-learn convention).

        Raises
        ------
        InputError
            When a name is not a setting of this class.
        """
        allowed = self._param_names()
        for name, value in params.items():
            if name not in allowed:
                raise InputError(
                    f"{name!r} is not a setting of {type(self).__name__}; settings: "
                    f"{', '.join(allowed)}"
                )
            setattr(self, name, value)
        return self

    def get_params_for_file(self) -> dict:
        """Settings as JSON-ready values: arrays and tuples become lists, as JSON reads them."""
        return {key: _json_ready(value) for key, value in self.get_params().items()}

    @classmethod
    def _params_from_file(cls, params: dict) -> dict:
        """Settings stored in a calibration file, as ``__init__`` takes them (a class whose
        settings changed maps older files' settings here)."""
        return params

    def _settings_repr(self) -> str:
        params = ", ".join(f"{k}={v!r}" for k, v in self.get_params().items())
        return f"{type(self).__name__}({params})"


def _json_ready(value):
    """Arrays, tuples and lists (of any depth and ragged) as lists; other values as given."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (tuple, list)):
        return [_json_ready(item) for item in value]
    if isinstance(value, np.generic):
        return value.item()
    return value
