"""The exceptions and the warning category of the taxel package.

Every exception the package raises on purpose derives from :class:`TaxelError`; each also
derives from the built-in exception a Python programmer would catch for the same trouble
(``LookupError``, ``OSError``, ``TimeoutError``, ``ValueError``). Messages are the ones the
``taxel`` command-line tool prints after ``error:``.
"""

import builtins


class TaxelError(Exception):
    """Base class of every error the taxel package raises on purpose."""


class DeviceNotFoundError(TaxelError, LookupError):
    """No attached board matches: none attached, none with the serial number asked for, or
    several attached and none chosen."""


class LinkError(TaxelError, OSError):
    """The link to the device failed: the port is missing or is not a serial port, it could not
    be opened, or the device closed the connection (unplugged). Raised by
    :meth:`taxel.Device.read_buffer`, ``buffer`` holds the sets collected before the failure (a
    :class:`taxel.Buffer`); otherwise it is ``None``."""

    def __init__(self, *args: object, buffer: object = None) -> None:
        super().__init__(*args)
        #: The sample sets collected before the link failed, or ``None``.
        self.buffer = buffer


class DeviceTimeoutError(TaxelError, builtins.TimeoutError):
    """Nothing arrived in time: no reply to a request, or no sample set within the timeout."""


class DeviceRefusedError(TaxelError):
    """The device answered a request with an error code (``code`` holds its name)."""

    def __init__(self, message: str, code: str = "") -> None:
        super().__init__(message)
        #: The device's error code, e.g. ``"NotSupported"``.
        self.code = code


class ProtocolVersionError(TaxelError):
    """The device speaks another protocol version than this package."""


class CalibrationError(TaxelError, ValueError):
    """A calibration file or data set cannot be read, fitted or used."""


class ConvertError(TaxelError, ValueError):
    """The data given to :func:`taxel.convert` cannot be converted."""


class DataLossError(TaxelError):
    """Sample sets were lost and the caller asked to be told by an exception: the background
    buffer was full, or sequence numbers had gaps. ``buffer`` holds what was collected (a
    :class:`taxel.Buffer`, whose counters say how many sets were lost and where)."""

    def __init__(self, message: str, buffer: object = None) -> None:
        super().__init__(message)
        #: The sample sets that were collected, with the loss counters.
        self.buffer = buffer


class TaxelWarning(UserWarning):
    """A warning of the package, in the words the ``taxel`` command prints after
    ``warning:``: a tare that did not finish or could not tare a taxel (:func:`taxel.convert`,
    :func:`taxel.convert_recording`), rows left out of a recording, what
    :meth:`taxel.Calibration.fit` warns about (rows outside the temperature law's range,
    intervals where converter noise exceeds the budget)."""
