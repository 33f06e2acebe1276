"""Capacitive tactile pads from Python: devices, the simulated device and conversion as numpy
arrays.

A pad has four taxels (C11, C12, C21, C22); a device reads one to eight pads. Every array over
the taxels is flat: ``taxels = 4 * pads`` columns, taxel ``4 * pad + k`` being taxel ``k`` of pad
``pad``, so a one-pad device and the default :class:`Simulator` give ``(4,)`` per sample set
and ``(N, 4)`` from a buffer, and a device of ``P`` pads ``(4 * P,)`` and ``(N, 4 * P)``;
``reshape(N, P, 4)`` separates the pads.

- :func:`list_devices`, :class:`Device`: attached boards; :meth:`Device.events` their
  :class:`DeviceEvent` objects.
- :class:`Simulator`: the simulated device (the firmware's own code) in this process, with the
  interface of :class:`Device`.
- :class:`Devices`: several boards and :class:`SimulatedBoard` objects on one host timeline.
- :class:`Buffer`: sets collected in the background; ``to_pandas()`` and ``save()``.
- :func:`convert`: capacitances to pressures with the pressure model, as ``taxel convert``;
  :func:`read_recording`, :func:`convert_recording`: recordings of the recording schema.
- :class:`Calibration`: calibration files, and fitting one from reference loads.
- :class:`Flags`: the flag bits of every taxel; the exceptions and :class:`TaxelWarning` in
  :mod:`taxel._errors`.
"""

from __future__ import annotations

import enum
import importlib.metadata as _metadata
import operator
import os
import warnings
from typing import Optional, Tuple

import numpy as np

from . import _taxel
from ._errors import (
    CalibrationError,
    ConvertError,
    DataLossError,
    DeviceNotFoundError,
    DeviceRefusedError,
    DeviceTimeoutError,
    LinkError,
    ProtocolVersionError,
    TaxelError,
    TaxelWarning,
)
from ._taxel import (
    Buffer,
    Calibration,
    Device,
    DeviceEvent,
    Devices,
    Recording,
    SampleSet,
    SimulatedBoard,
    Simulator,
    list_devices,
)

__all__ = [
    "Buffer",
    "Calibration",
    "CalibrationError",
    "ConvertError",
    "DataLossError",
    "Device",
    "DeviceEvent",
    "DeviceNotFoundError",
    "DeviceRefusedError",
    "DeviceTimeoutError",
    "Devices",
    "Flags",
    "LinkError",
    "ProtocolVersionError",
    "Recording",
    "SampleSet",
    "SimulatedBoard",
    "Simulator",
    "TIERS",
    "TaxelError",
    "TaxelWarning",
    "__version__",
    "convert",
    "convert_recording",
    "list_devices",
    "read_recording",
]

#: The installed package's version.
__version__: str = _metadata.version("taxel")

#: The inversion tiers of the pressure model, by name; ``"monotone-cubic"`` is the default.
TIERS: Tuple[str, ...] = tuple(_taxel.tier_names())


class Flags(enum.IntFlag):
    """The flags of one taxel, as the device and :func:`convert` set them (the documented
    names of the protocol and of ``taxel convert``'s flag cells, in upper case)."""

    BELOW_BASELINE = 1 << 0
    OVER_RANGE = 1 << 1
    SHORTED = 1 << 2
    OPEN = 1 << 3
    SATURATED = 1 << 4
    TEMPERATURE_MISSING = 1 << 5
    TEMPERATURE_OUT_OF_RANGE = 1 << 6
    NOT_TARED = 1 << 7
    CONVERTER_ERROR = 1 << 8
    STUCK = 1 << 9
    INVALID_INPUT = 1 << 10
    BASELINE_TRACKING_LIMIT = 1 << 11
    TEMPERATURE_FALLBACK = 1 << 12
    TEMPERATURE_IMPLAUSIBLE = 1 << 13
    BASELINE_FAR_FROM_CALIBRATION = 1 << 14

    @classmethod
    def _missing_(cls, value: object) -> "Optional[Flags]":
        # numpy's integers (a cell of ``sample.flags``) are not ``int``: the enum's own lookup
        # finds single bits by hash but refuses 0 and combinations of bits. Any integer that
        # ``operator.index`` accepts is read as its value.
        if isinstance(value, int):
            found: Optional[Flags] = super()._missing_(value)
            return found
        try:
            index = operator.index(value)  # type: ignore[arg-type]
        except TypeError:
            return None
        return cls(index)


def convert(
    capacitance_pf: "np.typing.ArrayLike",
    temp_c: "np.typing.ArrayLike",
    calibration: Optional[Calibration] = None,
    tier: Optional[str] = None,
    tare_rows: int = 1,
    time_s: "Optional[np.typing.ArrayLike]" = None,
    out: "Optional[Tuple[np.ndarray, np.ndarray]]" = None,
) -> Tuple[np.ndarray, np.ndarray]:
    """Converts capacitances to pressures with the pressure model, as ``taxel convert`` does.

    ``capacitance_pf``: shape ``(N, taxels)`` with ``taxels = 4 * pads`` (NaN: no reading);
    ``temp_c``: shape ``(N,)`` (every pad) or ``(N, pads)``, °C (NaN: no temperature);
    ``calibration``: default the built-in one; ``tier``: one of :data:`TIERS`, default
    ``"monotone-cubic"``; ``tare_rows``: each pad's baseline is the mean of its first this many
    readable rows (which are themselves flagged ``NOT_TARED``); ``time_s``: shape ``(N,)``,
    seconds, as a recording's ``time_s`` column (used by the temperature plausibility rule;
    without it that rule ignores the time between rows).

    Returns ``(pressure_kpa, flags)``: float64 and uint16 arrays of shape ``(N, taxels)``;
    a pressure is NaN where the model gives none, and the flags say why. With ``out=(pressure,
    flags)`` (as numpy's ``out=``) they are written into those arrays, which are returned: they
    must be writable, C-ordered, float64 and uint16, of shape ``(N, taxels)``, and share no
    memory with the inputs; converting many blocks into arrays made once saves allocating and
    first touching new memory each time. Each pad has a model of
    its own. With several pads, a row where a pad's four capacitances and its temperature are
    all NaN is that pad's frame missing from the set (as a buffer holds it, and as ``taxel
    convert`` reads a pad whose cells are all empty): its model skips the row, which gets NaN
    pressures and no flags. Problems with the tare are reported as :class:`TaxelWarning`. Bad
    shapes or values raise :class:`ConvertError`. The conversion runs with the GIL released
    (other threads run meanwhile) and answers Ctrl-C with ``KeyboardInterrupt`` within about
    20 ms.
    """
    capacitance = np.ascontiguousarray(capacitance_pf, dtype=np.float64)
    if capacitance.ndim != 2:
        raise ConvertError(
            f"capacitance_pf must have shape (N, taxels), with 4 taxels per pad; got shape {capacitance.shape}"
        )
    rows, taxels = capacitance.shape
    if rows == 0:
        raise ConvertError("capacitance_pf has no rows: nothing to convert")
    if taxels == 0 or taxels % 4 != 0:
        raise ConvertError(
            f"capacitance_pf has {taxels} columns: it needs 4 per pad (C11, C12, C21, C22)"
        )
    pads = taxels // 4
    temperature = np.asarray(temp_c, dtype=np.float64)
    if temperature.shape == (rows,):
        # One pad: a view with a second axis (no copy of a million temperatures).
        temperature = (
            temperature[:, None] if pads == 1 else np.repeat(temperature[:, None], pads, axis=1)
        )
    elif temperature.shape != (rows, pads):
        raise ConvertError(
            f"temp_c has shape {temperature.shape}; it must be ({rows},) or ({rows}, {pads})"
        )
    temperature = np.ascontiguousarray(temperature)
    times = None
    if time_s is not None:
        times = np.ascontiguousarray(time_s, dtype=np.float64)
        if times.shape != (rows,):
            raise ConvertError(f"time_s has shape {times.shape}; it must be ({rows},)")
    if isinstance(tare_rows, bool) or not isinstance(tare_rows, (int, np.integer)):
        raise ConvertError(f"tare_rows must be an integer (got {tare_rows!r})")
    if not 1 <= int(tare_rows) <= 65535:
        raise ConvertError(f"tare_rows must be 1 to 65535 (got {tare_rows})")
    if out is not None and (not isinstance(out, tuple) or len(out) != 2):
        raise ConvertError("out must be a tuple (pressure, flags) of two arrays")
    if out is not None and np.may_share_memory(out[0], out[1]):
        raise ConvertError("out's pressure and flags arrays share memory: each would overwrite the other")
    pressure_kpa, flags, messages = _taxel.convert_arrays(
        capacitance, temperature, times, calibration, tier, int(tare_rows), out
    )
    for message in messages:
        warnings.warn(message, TaxelWarning, stacklevel=2)
    return pressure_kpa, flags


def _warn_rows(path: "os.PathLike[str] | str", bad_rows: "list[str]", stacklevel: int) -> None:
    for reason in bad_rows:
        warnings.warn(f"{os.fspath(path)}: {reason} (row left out)", TaxelWarning, stacklevel=stacklevel + 1)


def read_recording(path: "os.PathLike[str] | str") -> Recording:
    """Reads a recording of the recording schema (what ``taxel record`` and the live view
    write): one row per pad per sample set of every device, as arrays (see :class:`Recording`).
    Rows that cannot be read are left out, each reported as a :class:`TaxelWarning` with its
    line; a file of another shape raises :class:`ConvertError`."""
    recording, bad_rows = _taxel.read_recording_rows(os.fspath(path))
    _warn_rows(path, bad_rows, stacklevel=2)
    return recording


def convert_recording(
    path: "os.PathLike[str] | str",
    calibration: Optional[Calibration] = None,
    tier: Optional[str] = None,
    tare_rows: Optional[int] = None,
    use_device_state: bool = True,
) -> Recording:
    """Converts a recording again exactly as ``taxel convert`` does (the same engine): every pad
    of every device through the model, force, centre of pressure and contact, with each
    device's recorded state (``NAME.dev<n>.device.json`` beside the file: calibration, tier,
    baselines) unless ``use_device_state`` is false; ``calibration``, ``tier`` and
    ``tare_rows`` replace its parts for every pad. Rows that cannot be read and tare problems
    are reported as :class:`TaxelWarning`."""
    if tare_rows is not None and (isinstance(tare_rows, bool) or not isinstance(tare_rows, (int, np.integer))):
        raise ConvertError(f"tare_rows must be an integer (got {tare_rows!r})")
    if tare_rows is not None and not 1 <= int(tare_rows) <= 65535:
        raise ConvertError(f"tare_rows must be 1 to 65535 (got {tare_rows})")
    recording, bad_rows, tare_warnings = _taxel.convert_recording_rows(
        os.fspath(path),
        calibration,
        tier,
        None if tare_rows is None else int(tare_rows),
        use_device_state,
    )
    _warn_rows(path, bad_rows, stacklevel=2)
    for message in tare_warnings:
        warnings.warn(message, TaxelWarning, stacklevel=2)
    return recording
