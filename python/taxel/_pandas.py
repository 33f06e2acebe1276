"""Buffers and recordings as pandas tables of the recording schema (``Buffer.to_pandas()``,
``Recording.to_pandas()``): one row per pad per sample set, the schema's columns in its order
(``taxel record --help`` lists them), so that a live buffer and a recording file give the same
table. Where the file has text the table has numbers: flags are integers (bits of
:class:`taxel.Flags`), ``partial`` and ``contact`` booleans, empty cells NaN (and ``""`` for the
temperature source of a missing frame, as :func:`taxel.read_recording` gives it).

pandas is optional: without it these raise an ``ImportError`` that says how to install it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Dict

import numpy as np
import numpy.typing as npt

from . import _taxel

if TYPE_CHECKING:
    import pandas

#: The flag and pressure column suffixes of taxels C11, C12, C21, C22.
_TAXEL_SUFFIXES = ("11", "12", "21", "22")


_MISSING_PANDAS = (
    "to_pandas() needs pandas, which is not installed: pip install pandas "
    "(or pip install \"taxel[pandas]\")"
)


def _require_pandas() -> None:
    try:
        import pandas  # noqa: F401
    except ImportError as error:
        raise ImportError(_MISSING_PANDAS) from error


def _frame(columns: Dict[str, "npt.ArrayLike"]) -> "pandas.DataFrame":
    try:
        import pandas
    except ImportError as error:
        raise ImportError(_MISSING_PANDAS) from error
    order = _taxel.recording_columns()
    if set(order) != set(columns):
        raise RuntimeError(
            f"the table's columns {sorted(columns)} are not the recording schema's {order}"
        )
    return pandas.DataFrame({name: columns[name] for name in order})


def _taxel_columns(
    columns: Dict[str, "npt.ArrayLike"],
    capacitance_pf: "npt.NDArray[np.float64]",
    pressure_kpa: "npt.NDArray[np.float64]",
    flags: "npt.NDArray[np.uint16]",
) -> None:
    for k, suffix in enumerate(_TAXEL_SUFFIXES):
        columns[f"c{suffix}_pf"] = capacitance_pf[:, k]
    for k, suffix in enumerate(_TAXEL_SUFFIXES):
        columns[f"p{suffix}_kpa"] = pressure_kpa[:, k]
    for k, suffix in enumerate(_TAXEL_SUFFIXES):
        columns[f"flags{suffix}"] = flags[:, k]


def buffer_frame(buffer: "_taxel.Buffer") -> "pandas.DataFrame":
    """A buffer's sets as the recording schema's long table (see the module documentation)."""
    _require_pandas()
    sets, pads = len(buffer), buffer.pads
    rows = sets * pads
    missing = buffer.missing.reshape(rows)
    pad_time_us = buffer.pad_device_time_us.reshape(rows)
    device_time_s = np.where(missing, np.nan, pad_time_us / 1e6)
    sources = np.where(missing, "", buffer.temperature_source.reshape(rows)).astype(object)
    columns: Dict[str, "npt.ArrayLike"] = {
        "host_time_s": np.repeat(buffer.host_time_s, pads),
        "device": np.full(rows, buffer.device, dtype=np.int64),
        "pad": np.tile(np.arange(pads, dtype=np.int64), sets),
        "seq": np.repeat(buffer.sequence, pads),
        "device_time_s": device_time_s,
        "sync_error_ms": np.repeat(buffer.sync_error_ms, pads),
        "temp_c": buffer.temperature_c.reshape(rows),
        "temp_source": sources,
        "force_n": buffer.force_n.reshape(rows),
        "cop_x_mm": buffer.cop_mm[:, :, 0].reshape(rows),
        "cop_y_mm": buffer.cop_mm[:, :, 1].reshape(rows),
        "partial": buffer.partial.reshape(rows),
        "contact": buffer.contact.reshape(rows),
        "marker": np.full(rows, "", dtype=object),
    }
    _taxel_columns(
        columns,
        buffer.capacitance_pf.reshape(rows, 4),
        buffer.pressure_kpa.reshape(rows, 4),
        buffer.flags.reshape(rows, 4),
    )
    return _frame(columns)


def recording_frame(recording: "_taxel.Recording") -> "pandas.DataFrame":
    """A recording's rows as the recording schema's long table (see the module documentation)."""
    _require_pandas()
    rows = len(recording)
    markers = np.full(rows, "", dtype=object)
    for row, label in recording.markers:
        markers[row] = label
    columns: Dict[str, "npt.ArrayLike"] = {
        "host_time_s": recording.host_time_s,
        "device": recording.device,
        "pad": recording.pad,
        "seq": recording.sequence,
        "device_time_s": recording.device_time_s,
        "sync_error_ms": recording.sync_error_ms,
        "temp_c": recording.temperature_c,
        "temp_source": np.array(recording.temperature_source, dtype=object),
        "force_n": recording.force_n,
        "cop_x_mm": recording.cop_mm[:, 0],
        "cop_y_mm": recording.cop_mm[:, 1],
        "partial": recording.partial,
        "contact": recording.contact,
        "marker": markers,
    }
    _taxel_columns(columns, recording.capacitance_pf, recording.pressure_kpa, recording.flags)
    return _frame(columns)
