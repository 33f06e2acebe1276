"""Type stubs of the native module ``taxel._taxel`` (re-exported by ``taxel``)."""

from types import TracebackType
import os
from typing import Any, Dict, Iterable, Iterator, List, Optional, Tuple, Type, Union

import numpy as np
import numpy.typing as npt
import pandas

def list_devices() -> List[Dict[str, Any]]:
    """The boards attached by USB with the pad's VID:PID, sorted by port: one dict per board
    with ``port``, ``serial_number``, ``manufacturer``, ``product``, ``vid`` and ``pid``."""

def flag_bits() -> List[Tuple[str, int]]:
    """The documented flag names and their bits, in bit order (the source of ``taxel.Flags``)."""

def tier_names() -> List[str]:
    """The inversion tiers' names, in id order."""

def recording_columns() -> List[str]:
    """The recording schema's columns, in order (the header ``taxel record`` writes)."""

def convert_arrays(
    capacitance_pf: npt.ArrayLike,
    temp_c: npt.ArrayLike,
    time_s: Optional[npt.ArrayLike],
    calibration: Optional["Calibration"],
    tier: Optional[str],
    tare_rows: int,
    out: Optional[Tuple[npt.NDArray[np.float64], npt.NDArray[np.uint16]]] = None,
) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.uint16], List[str]]:
    """The native half of :func:`taxel.convert` (array-likes, read as C-ordered float64)."""

class SampleSet:
    """One sample set of every pad. Arrays over the taxels have shape ``(taxels,)`` with
    ``taxels = 4 * pads`` (taxel ``4 * pad + k`` is taxel ``k`` of pad ``pad``); arrays over the
    pads have shape ``(pads,)``; ``cop_mm`` ``(pads, 2)``."""

    @property
    def device(self) -> int:
        """The device (0 for :class:`Device`; its index for :class:`Devices`)."""
    @property
    def sequence(self) -> int:
        """The set's sequence number (one more per set acquired; wraps at 2**32)."""
    @property
    def device_time_us(self) -> int:
        """The device clock at the conversion, µs since the device booted."""
    @property
    def device_time_s(self) -> float:
        """The device clock at the conversion, seconds since the device booted."""
    @property
    def host_time_s(self) -> float:
        """The host clock of the set, seconds since the Unix epoch: its arrival
        (:class:`Device`), or its device time mapped onto the host clock (:class:`Devices`)."""
    @property
    def sync_error_ms(self) -> float:
        """Bound on ``host_time_s``'s error, ms; NaN when it is the arrival."""
    @property
    def pads(self) -> int:
        """The number of pads."""
    @property
    def temperature_c(self) -> npt.NDArray[np.float64]:
        """Each pad's temperature, °C, ``(pads,)``; NaN where there is none."""
    @property
    def temperature_source(self) -> List[str]:
        """Each pad's temperature source: ``tmp117``, ``mcu_internal``, ``last_known`` or ``none``."""
    @property
    def pressure_kpa(self) -> npt.NDArray[np.float64]:
        """Pressure per taxel, kPa, ``(taxels,)``; NaN where the model gives none."""
    @property
    def capacitance_pf(self) -> npt.NDArray[np.float64]:
        """Capacitance per taxel, pF, ``(taxels,)``; NaN for a missing pad frame."""
    @property
    def flags(self) -> npt.NDArray[np.uint16]:
        """Flags per taxel (bits of :class:`taxel.Flags`), ``(taxels,)``."""
    @property
    def force_n(self) -> npt.NDArray[np.float64]:
        """Each pad's total normal force, N, ``(pads,)``; NaN where there is none."""
    @property
    def cop_mm(self) -> npt.NDArray[np.float64]:
        """Each pad's centre of pressure, mm, ``(pads, 2)`` (x, y); NaN where there is none."""
    @property
    def contact(self) -> npt.NDArray[np.bool_]:
        """Whether each pad is in contact (the device's detector), ``(pads,)``."""
    @property
    def partial(self) -> npt.NDArray[np.bool_]:
        """Whether faulted taxels were left out of each pad's force and centre, ``(pads,)``."""
    @property
    def missing_pads(self) -> List[int]:
        """Pads whose frame of this set never arrived."""
    @property
    def sets_missing_before(self) -> int:
        """Sample sets missing just before this one in the sequence numbers (0 normally)."""

class Buffer:
    """Sample sets of one device collected in the background: ``(N,)``, ``(N, pads)``,
    ``(N, pads, 2)`` and ``(N, taxels)`` arrays, and the counts of sets lost since the previous
    :meth:`Device.read_buffer`."""

    device: int
    """The device (0 for :class:`Device`; its index for :class:`Devices`)."""
    sequence: npt.NDArray[np.int64]
    """Sequence numbers, ``(N,)``."""
    device_time_us: npt.NDArray[np.int64]
    """Device clock at each set (pad 0's conversion), µs since boot, ``(N,)``."""
    pad_device_time_us: npt.NDArray[np.int64]
    """Device clock at each pad's conversion, µs since boot, ``(N, pads)``; -1 if missing."""
    host_time_s: npt.NDArray[np.float64]
    """Host clock of each set, seconds since the Unix epoch, ``(N,)``: its arrival
    (:class:`Device`) or its stamp on the shared timeline (:class:`Devices`)."""
    sync_error_ms: npt.NDArray[np.float64]
    """Bound on ``host_time_s``'s error, ms, ``(N,)``; NaN where it is the arrival."""
    temperature_c: npt.NDArray[np.float64]
    """Temperature per pad, °C, ``(N, pads)``."""
    temperature_source: npt.NDArray[np.str_]
    """Where each temperature came from, ``(N, pads)`` strings."""
    pressure_kpa: npt.NDArray[np.float64]
    """Pressure per taxel, kPa, ``(N, taxels)``."""
    capacitance_pf: npt.NDArray[np.float64]
    """Capacitance per taxel, pF, ``(N, taxels)``."""
    flags: npt.NDArray[np.uint16]
    """Flags per taxel, ``(N, taxels)``."""
    force_n: npt.NDArray[np.float64]
    """Total normal force per pad, N, ``(N, pads)``."""
    cop_mm: npt.NDArray[np.float64]
    """Centre of pressure per pad, mm, ``(N, pads, 2)`` (x, y); NaN where there is none."""
    contact: npt.NDArray[np.bool_]
    """Whether each pad is in contact, ``(N, pads)``."""
    partial: npt.NDArray[np.bool_]
    """Whether faulted taxels were left out of a pad's force and centre, ``(N, pads)``."""
    missing: npt.NDArray[np.bool_]
    """Whether a pad's frame of the set never arrived, ``(N, pads)``."""
    sets_missing_before: npt.NDArray[np.int64]
    """Sets missing just before each one in the sequence numbers, ``(N,)``."""
    pads: int
    """The number of pads."""
    overflowed_sets: int
    """Sets that arrived while the buffer was full and were discarded."""
    sequence_gap_sets: int
    """Sets missing from the sequence numbers among these (sum of ``sets_missing_before``)."""
    @property
    def lost_sets(self) -> int:
        """``overflowed_sets + sequence_gap_sets``."""
    def to_pandas(self) -> pandas.DataFrame:
        """The sets as the recording schema's long table: one row per pad per set (needs
        pandas)."""
    def save(self, path: Union[str, "os.PathLike[str]"]) -> None:
        """Writes the sets as a recording of the schema (what ``taxel record`` writes) and,
        beside it, ``PATH.dev<n>.device.json``: what the device computed them with."""
    def __len__(self) -> int: ...

class DeviceEvent:
    """Something a device reported: contact started or ended, a tare finished or refused,
    the temperature source changed, the converter re-initialised, the flash calibration
    corrupt."""

    @property
    def kind(self) -> str:
        """``contact_started``, ``contact_ended``, ``tare_finished``, ``tare_refused``,
        ``temperature_source_changed``, ``converter_reinitialised`` or
        ``calibration_flash_corrupt``."""
    @property
    def pad(self) -> Optional[int]:
        """The pad it concerns (``None`` for the whole device)."""
    @property
    def device(self) -> int:
        """The device (0 for :class:`Device`; its index for :class:`Devices`)."""
    @property
    def device_time_us(self) -> int:
        """The device clock when it happened, µs since boot."""
    @property
    def device_time_s(self) -> float:
        """The device clock when it happened, seconds since boot."""
    @property
    def host_time_s(self) -> float:
        """The host clock when it arrived, seconds since the Unix epoch."""
    @property
    def fields(self) -> Dict[str, Any]:
        """The kind's own fields (``tared``, ``refused``, ``source``, ``reinit_count``, ...)."""
    @property
    def text(self) -> str:
        """The event in words, as ``taxel record`` prints it."""
    def __eq__(self, other: object) -> bool: ...

class Calibration:
    """A calibration: per taxel the curve of dC/C0 against pressure, parasitic and unloaded
    capacitances; the temperature law; the fault thresholds."""

    @staticmethod
    def default() -> "Calibration":
        """The built-in default calibration (the article's curve)."""
    @staticmethod
    def load(path: Union[str, "os.PathLike[str]"]) -> "Calibration":
        """Reads a calibration file (raises :class:`taxel.CalibrationError`)."""
    @staticmethod
    def from_json(text: str) -> "Calibration":
        """Reads a calibration from the file's JSON text."""
    def save(self, path: Union[str, "os.PathLike[str]"]) -> None:
        """Writes the calibration file (under a temporary name, renamed when complete)."""
    def to_json(self) -> str:
        """The calibration file's JSON text."""
    @staticmethod
    def fit(
        pressure_kpa: npt.ArrayLike,
        capacitance_pf: npt.ArrayLike,
        temp_c: Optional[npt.ArrayLike] = None,
        id: int = 1,
        parasitic_pf: float = 0.0,
        budget_kpa: float = 0.5,
    ) -> "Calibration":
        """Fits a calibration from reference loads: ``pressure_kpa`` (N,), ``capacitance_pf``
        (N, 4), ``temp_c`` (N,) or None; as ``taxel calibrate``."""
    @property
    def id(self) -> int:
        """The calibration id."""
    @property
    def fit_report(self) -> Optional[str]:
        """The report of :meth:`fit`, as ``taxel calibrate`` prints it."""
    @property
    def leave_one_out(self) -> List[Dict[str, Any]]:
        """The cross-validation of :meth:`fit`, one dict per taxel and tier."""
    @property
    def fit_warnings(self) -> List[str]:
        """The warnings of :meth:`fit` (also issued as :class:`taxel.TaxelWarning`)."""
    def __eq__(self, other: object) -> bool: ...

class Device:
    """A board, with its sample sets and commands; a context manager and an iterator of
    :class:`SampleSet`."""

    def __init__(
        self,
        port: Optional[str] = None,
        serial: Optional[str] = None,
        timeout: float = 2.0,
        queue_sets: int = 65_536,
    ) -> None:
        """Opens the board on ``port``, or with USB serial number ``serial``, or the only one;
        ``queue_sets`` sets are kept for :meth:`read` while nobody reads."""
    @property
    def info(self) -> Dict[str, Any]:
        """Protocol and firmware version, board serial, calibration id and source, rate, tier,
        pad count, streaming, port."""
    @property
    def pads(self) -> int:
        """The number of pads of each sample set."""
    @property
    def taxels(self) -> int:
        """The number of taxels of each sample set (4 per pad)."""
    def pad_info(self, pad: int) -> Dict[str, Any]:
        """Pad ``pad`` as the device reports it: channel, calibration id and source, tier,
        ``role`` and ``taxels`` (a (4, 3) array of each taxel's centre x, y in mm and area in
        mm²), what the device computes the pad's force with."""
    def read(self, timeout: Optional[float] = None) -> SampleSet:
        """The oldest sample set not yet read (a queue; raises
        :class:`taxel.DeviceTimeoutError` if none in time)."""
    def latest(self, timeout: Optional[float] = None) -> SampleSet:
        """The newest complete sample set (older queued ones are discarded), or the next."""
    def __iter__(self) -> Iterator[SampleSet]: ...
    def __next__(self) -> SampleSet: ...
    def start_buffering(self, capacity_sets: int = 1_000_000) -> None:
        """Starts collecting every sample set in the background."""
    def read_buffer(self, strict: bool = True) -> Buffer:
        """The sets collected since the last call; with ``strict``, lost sets raise
        :class:`taxel.DataLossError` (its ``buffer`` holds what was collected); a failed link
        raises :class:`taxel.LinkError`, whose ``buffer`` holds the sets collected before it."""
    def stop_buffering(self) -> Buffer:
        """Stops collecting in the background; returns the sets not yet read."""
    @property
    def buffering(self) -> bool:
        """Whether sets are being collected in the background."""
    def events(self) -> List[DeviceEvent]:
        """The device events that arrived since the last call, oldest first."""
    def tare(self, sample_sets: int = 64, pad: Optional[int] = None) -> None:
        """Tares every pad (or ``pad`` only) on the mean of the next ``sample_sets`` sets."""
    def set_rate(self, rate_sps: int) -> None:
        """Sets the converter rate: 100, 200 or 400 conversions per second."""
    def set_tier(self, tier: str) -> None:
        """Selects the pressure-model tier (see :data:`taxel.TIERS`)."""
    def set_use_case(self, use_case: Union[str, Dict[str, float]]) -> str:
        """Lets the device choose the tier for a use case; returns the tier chosen."""
    def read_calibration(self, pad: int = 0) -> Calibration:
        """The calibration pad ``pad`` uses."""
    def write_calibration(
        self, calibration: Calibration, pad: Optional[int] = None, save: bool = False
    ) -> None:
        """Writes a calibration to every pad (or ``pad``), and to flash with ``save``."""
    def save_calibration(self) -> None:
        """Saves the calibration in use to the device's flash."""
    def restore_defaults(self) -> None:
        """Replaces every pad's calibration in RAM by the built-in default."""
    def read_counters(self) -> Dict[str, int]:
        """The device's health counters since it booted."""
    @property
    def stats(self) -> Dict[str, int]:
        """This connection's accounting of sets, gaps and drops."""
    def close(self) -> None:
        """Stops the stream and closes the port. Idempotent; safe from any thread or a signal
        handler (a read waiting meanwhile raises :class:`taxel.LinkError`)."""
    @property
    def closed(self) -> bool:
        """Whether :meth:`close` was called."""
    def __enter__(self) -> "Device": ...
    def __exit__(
        self,
        exception_type: Optional[Type[BaseException]],
        exception: Optional[BaseException],
        traceback: Optional[TracebackType],
    ) -> bool: ...

class Simulator(Device):
    """The simulated device in this process, with the interface of :class:`Device`."""

    def __init__(
        self,
        scene: Optional[str] = None,
        speed: Optional[float] = 1.0,
        seed: int = 1,
        pads: Optional[int] = None,
        timeout: float = 2.0,
        link_buffer_bytes: int = 262_144,
        queue_sets: int = 65_536,
    ) -> None:
        """Starts the simulated device playing ``scene`` at ``speed`` times real time (None: as
        fast as possible)."""
    @property
    def scene(self) -> str:
        """The scene's name."""

class SimulatedBoard:
    """A simulated board to start among :class:`Devices` (what :class:`Simulator` takes)."""

    scene: Optional[str]
    speed: Optional[float]
    seed: int
    pads: Optional[int]
    link_buffer_bytes: int
    def __init__(
        self,
        scene: Optional[str] = None,
        speed: Optional[float] = 1.0,
        seed: int = 1,
        pads: Optional[int] = None,
        link_buffer_bytes: int = 262_144,
    ) -> None: ...

class Devices:
    """Several devices on one host timeline, read through one host-library worker; sets
    stamped as ``taxel record`` stamps them and merged in host-time order."""

    def __init__(
        self,
        sources: Iterable[Union[str, "os.PathLike[str]", SimulatedBoard]],
        timeout: float = 2.0,
        queue_sets: int = 65_536,
    ) -> None:
        """Opens every device of ``sources`` (serial ports' paths and simulated boards)."""
    def __len__(self) -> int: ...
    @property
    def info(self) -> List[Dict[str, Any]]:
        """Each device's identity, in the order given."""
    @property
    def pads(self) -> List[int]:
        """Each device's number of pads."""
    @property
    def taxels(self) -> List[int]:
        """Each device's number of taxels."""
    def read(self, timeout: Optional[float] = None) -> SampleSet:
        """The next sample set in host-time order, of any device."""
    def __iter__(self) -> Iterator[SampleSet]: ...
    def __next__(self) -> SampleSet: ...
    def events(self) -> List[DeviceEvent]:
        """Every device's events that arrived since the last call."""
    def start_buffering(self, capacity_sets: int = 1_000_000) -> None:
        """Starts collecting every device's sets in the background."""
    def read_buffer(self, strict: bool = True) -> List[Buffer]:
        """The sets collected since the last call, one buffer per device."""
    def stop_buffering(self) -> List[Buffer]:
        """Stops collecting; returns the sets not yet read, one buffer per device."""
    @property
    def buffering(self) -> bool:
        """Whether sets are being collected in the background."""
    def tare(self, sample_sets: int = 64, device: Optional[int] = None, pad: Optional[int] = None) -> None:
        """Tares every pad of every device (or of ``device``, or only its pad ``pad``)."""
    @property
    def stats(self) -> List[Dict[str, int]]:
        """Each device's accounting."""
    def close(self) -> None:
        """Stops every stream and closes the devices. Idempotent; safe from any thread."""
    @property
    def closed(self) -> bool:
        """Whether :meth:`close` was called."""
    def __enter__(self) -> "Devices": ...
    def __exit__(
        self,
        exception_type: Optional[Type[BaseException]],
        exception: Optional[BaseException],
        traceback: Optional[TracebackType],
    ) -> bool: ...

class Recording:
    """A recording as arrays: one row per pad per sample set (the recording schema)."""

    host_time_s: npt.NDArray[np.float64]
    device: npt.NDArray[np.int64]
    pad: npt.NDArray[np.int64]
    sequence: npt.NDArray[np.int64]
    device_time_s: npt.NDArray[np.float64]
    sync_error_ms: npt.NDArray[np.float64]
    temperature_c: npt.NDArray[np.float64]
    temperature_source: List[str]
    capacitance_pf: npt.NDArray[np.float64]
    pressure_kpa: npt.NDArray[np.float64]
    flags: npt.NDArray[np.uint16]
    force_n: npt.NDArray[np.float64]
    cop_mm: npt.NDArray[np.float64]
    partial: npt.NDArray[np.bool_]
    contact: npt.NDArray[np.bool_]
    missing: npt.NDArray[np.bool_]
    markers: List[Tuple[int, str]]
    def to_pandas(self) -> pandas.DataFrame:
        """The recording as the recording schema's long table (needs pandas)."""
    def __len__(self) -> int: ...

def read_recording_rows(path: str) -> Tuple[Recording, List[str]]:
    """The native half of :func:`taxel.read_recording`."""

def convert_recording_rows(
    path: str,
    calibration: Optional[Calibration],
    tier: Optional[str],
    tare_rows: Optional[int],
    use_device_state: bool,
) -> Tuple[Recording, List[str], List[str]]:
    """The native half of :func:`taxel.convert_recording`."""
