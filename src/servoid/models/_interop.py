"""Conversion to and from scipy.signal and python-control objects.

python-control is optional (``pip install servoid[control]``) and is
imported only when one of its converters is called.  A
:class:`PolynomialModel` travels as its transfer function from the input
(``model.transfer_function(0)``); its noise model stays behind, since
neither target has a place for it.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .._errors import ModelError, OptionTypeError
from .._lazy import signal
from ._polynomial import PolynomialModel
from ._statespace import StateSpace
from ._transfer import TransferFunction

__all__ = ["from_control", "from_scipy", "to_control", "to_scipy"]

Model = TransferFunction | StateSpace | PolynomialModel


def to_scipy(model: Model) -> signal.TransferFunction | signal.StateSpace:
    """Return the equivalent scipy.signal system.

    Parameters
    ----------
    model : TransferFunction, StateSpace or PolynomialModel
        The model; the discretisation method is not carried over.  A
        single-input PolynomialModel becomes its transfer function from
        the input, ``model.transfer_function(input=0)``: its noise model
        C/(A·D) is dropped.

    Returns
    -------
    scipy.signal.TransferFunction or scipy.signal.StateSpace
        Continuous (lti) for ``dt=None``, else discrete (dlti) with the same dt.

    Raises
    ------
    ModelError
        For a transfer function with a delay (scipy has none; discretise
        it with ``c2d`` first) or a PolynomialModel with several inputs
        (convert ``model.transfer_function(input=i)`` instead).
    """
    model = _plain(model, "scipy.signal", "to_scipy")
    kw = {} if model.dt is None else {"dt": model.dt}
    if isinstance(model, TransferFunction):
        return signal.TransferFunction(np.array(model.num), np.array(model.den), **kw)
    return signal.StateSpace(
        np.array(model.A), np.array(model.B), np.array(model.C), np.array(model.D), **kw
    )


def from_scipy(obj: signal.lti | signal.dlti) -> TransferFunction | StateSpace:
    """Return a servoid model from a scipy.signal system.

    Parameters
    ----------
    obj : scipy.signal.lti or scipy.signal.dlti
        A TransferFunction, ZerosPolesGain (converted to a transfer
        function) or StateSpace; SISO for transfer functions.

    Returns
    -------
    TransferFunction or StateSpace
        With ``dt=None`` for continuous systems.
    """
    if not isinstance(obj, (signal.lti, signal.dlti)):
        raise OptionTypeError(f"obj must be a scipy.signal lti or dlti system, "
                              f"got {type(obj).__name__}")
    dt = getattr(obj, "dt", None)
    if isinstance(obj, signal.StateSpace):
        return StateSpace(obj.A, obj.B, obj.C, obj.D, dt)
    tf = obj.to_tf()
    num = np.asarray(tf.num)
    if num.ndim > 1:
        if num.shape[0] != 1:
            raise ModelError(
                f"only SISO transfer functions are supported, got {num.shape[0]} outputs"
            )
        num = num[0]
    return TransferFunction(num, tf.den, dt)


def to_control(model: Model) -> Any:
    """Return the equivalent python-control system.

    Parameters
    ----------
    model : TransferFunction, StateSpace or PolynomialModel
        The model.  A single-input PolynomialModel becomes its transfer
        function from the input, ``model.transfer_function(input=0)``:
        its noise model C/(A·D) is dropped.

    Returns
    -------
    control.TransferFunction or control.StateSpace
        With python-control's ``dt = 0`` for continuous time.

    Raises
    ------
    ModelError
        For a transfer function with a delay (python-control's transfer
        functions have none; discretise it with ``c2d`` first, or use
        ``control.pade`` for an approximation), or a PolynomialModel with
        several inputs (convert ``model.transfer_function(input=i)``).
    """
    model = _plain(model, "python-control", "to_control")
    control = _import_control()
    dt = 0 if model.dt is None else model.dt
    if isinstance(model, TransferFunction):
        return control.tf(np.array(model.num), np.array(model.den), dt)
    return control.ss(
        np.array(model.A), np.array(model.B), np.array(model.C), np.array(model.D), dt
    )


def from_control(obj: Any) -> TransferFunction | StateSpace:
    """Return a servoid model from a python-control system.

    Parameters
    ----------
    obj : control.TransferFunction or control.StateSpace
        SISO for transfer functions.  python-control's ``dt = 0`` and
        ``dt = None`` (unspecified time base) become continuous time;
        ``dt = True`` (discrete, unknown period) is refused.

    Returns
    -------
    TransferFunction or StateSpace
        The servoid model.
    """
    control = _import_control()
    dt = obj.dt if hasattr(obj, "dt") else None
    if dt is True:
        raise ModelError("python-control dt=True (discrete, unspecified period) has no dt [s]")
    dt = None if dt is None or dt == 0 else float(dt)
    if isinstance(obj, control.StateSpace):
        return StateSpace(obj.A, obj.B, obj.C, obj.D, dt)
    if isinstance(obj, control.TransferFunction):
        if obj.ninputs != 1 or obj.noutputs != 1:
            raise ModelError(
                f"only SISO transfer functions are supported, got {obj.noutputs}×{obj.ninputs}"
            )
        return TransferFunction(obj.num[0][0], obj.den[0][0], dt)
    raise OptionTypeError(
        f"obj must be a control.TransferFunction or control.StateSpace, got {type(obj).__name__}"
    )


def _plain(model: object, target: str, caller: str) -> TransferFunction | StateSpace:
    """The TransferFunction or StateSpace ``target`` receives, or a servoid error."""
    if not isinstance(model, (PolynomialModel, TransferFunction, StateSpace)) and \
            hasattr(model, "model"):  # an Estimate or an InnovationModel: its deterministic part
        from ._generic import as_lti

        model = as_lti(model)
    if isinstance(model, PolynomialModel):
        if model.n_inputs != 1:
            raise ModelError(
                f"{target} receives one transfer function and this PolynomialModel has "
                f"{model.n_inputs} inputs; convert one at a time: "
                f"{caller}(model.transfer_function(input=i)) for i in 0..{model.n_inputs - 1}"
            )
        return model.transfer_function(input=0)
    if not isinstance(model, (TransferFunction, StateSpace)):
        raise OptionTypeError(
            f"model must be a TransferFunction, StateSpace or PolynomialModel, got "
            f"{type(model).__name__}; build one of them first (a PolynomialModel converts "
            "through model.transfer_function(input=i))"
        )
    _refuse_delay(model, target)
    return model


def _refuse_delay(model: TransferFunction | StateSpace, target: str) -> None:
    if isinstance(model, TransferFunction) and model.delay:
        raise ModelError(
            f"{target} transfer functions have no delay and this model has delay = "
            f"{model.delay} s; discretise it with c2d first (the delay becomes poles at z = 0), "
            "or drop the delay on purpose with dataclasses.replace(model, delay=0.0)"
        )


def _import_control() -> Any:
    try:
        import control
    except ImportError as exc:
        raise ImportError(
            "python-control is required for this conversion: pip install servoid[control]"
        ) from exc
    return control
