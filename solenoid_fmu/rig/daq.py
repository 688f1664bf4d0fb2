"""The rig's data acquisition: true signals in, a recording as the sensors and converters see it out.

:class:`TruthResult` is what the truth gives the DAQ (noise-free signals at the sample times);
:class:`DataAcquisition` holds the sensor noise, offsets, force-sensor gain and ADC quantization;
:func:`measure` applies them, plus each excitation's own voltage offset and current-channel delay.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..measure import make_recording
from .errors import RigError, positive
from .excitation import Excitation

__all__ = ["DataAcquisition", "TruthResult", "measure"]


@dataclass(frozen=True)
class DataAcquisition:
    """Sensor noise, offsets and quantization of the data acquisition.

    Parameters
    ----------
    voltage_noise_V, current_noise_A, force_noise_N, position_noise_m : float
        Standard deviation of white Gaussian sensor noise per channel [V], [A], [N], [m].
    voltage_offset_V, current_offset_A : float
        Constant offsets of the voltage and current channels [V], [A].
    adc_bits : int
        ADC resolution; a channel with full-scale range ``+-FS`` has the step ``2 FS / 2**bits``.
    voltage_range_V, current_range_A, force_range_N : float
        Full-scale ranges (+-) [V], [A], [N].
    position_resolution_m : float
        Resolution of the position encoder [m].
    force_gain, force_offset_N : float
        Calibration error of the force sensor: measured = gain * true + offset [1], [N]
        (a sensor fault; 1 and 0 for a calibrated sensor).
    """

    voltage_noise_V: float = 3e-3
    current_noise_A: float = 0.5e-3
    force_noise_N: float = 0.05
    position_noise_m: float = 0.5e-6
    voltage_offset_V: float = 5e-3
    current_offset_A: float = 0.0
    adc_bits: int = 16
    voltage_range_V: float = 100.0
    current_range_A: float = 5.0
    force_range_N: float = 100.0
    position_resolution_m: float = 1e-6
    force_gain: float = 1.0
    force_offset_N: float = 0.0

    def __post_init__(self):
        for name in ("voltage_noise_V", "current_noise_A", "force_noise_N", "position_noise_m"):
            positive(name, getattr(self, name), allow_zero=True)
        for name in ("voltage_range_V", "current_range_A", "force_range_N", "position_resolution_m"):
            positive(name, getattr(self, name))
        positive("force_gain", self.force_gain)
        for name in ("voltage_offset_V", "current_offset_A", "force_offset_N"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v)):
                raise RigError(f"{name} must be a finite number, got {v!r}")
        if not (isinstance(self.adc_bits, int) and 4 <= self.adc_bits <= 32):
            raise RigError(f"adc_bits must be an integer in 4..32, got {self.adc_bits!r}")



@dataclass
class TruthResult:
    """True (noise-free) signals of one excitation at the sample times, SI units.

    Attributes
    ----------
    time_s, voltage_V, current_A, psi_Wb, force_N, position_m : numpy.ndarray, shape (n,)
        Sample times [s]; coil voltage [V] and coil current [A] as means over the sample
        interval ending at each sample (integrating converters; sample 0: instantaneous), so
        ``sum`` of the trapezoid of ``U - R i`` reproduces ``psi_Wb`` (paper eq. 4) up to half a
        sample; flux linkage [Wb], measured force (magnetic force plus friction) [N] and
        working gap [m] at the sample times.
    force_magnetic_N, i_hyst_A, i_eddy_A, temperature_C : numpy.ndarray, shape (n,)
        Magnetic force alone [N], hysteresis current [A], eddy current [A], coil temperature [degC].
    resistance_start_ohm, temperature_start_C, temperature_end_C : float
        Coil resistance [ohm] and temperature [degC] at the start, temperature at the end.
    """

    time_s: np.ndarray
    voltage_V: np.ndarray
    current_A: np.ndarray
    psi_Wb: np.ndarray
    force_N: np.ndarray
    position_m: np.ndarray
    force_magnetic_N: np.ndarray
    i_hyst_A: np.ndarray
    i_eddy_A: np.ndarray
    temperature_C: np.ndarray
    resistance_start_ohm: float
    temperature_start_C: float
    temperature_end_C: float



def _quantize(v: np.ndarray, step: float) -> np.ndarray:
    return np.round(v / step) * step


def measure(truth: TruthResult, exc: Excitation, daq: DataAcquisition | None, rng: np.random.Generator,
            solenoid: str = "PS45"):
    """Turn true signals into a :class:`~solenoid_fmu.measure.Recording` as the rig's DAQ sees them.

    Parameters
    ----------
    truth : TruthResult
        Output of :meth:`~solenoid_fmu.rig.TruthModel.simulate`.
    exc : Excitation
        The excitation (kind, channels, notes).
    daq : DataAcquisition or None
        Noise, offsets and quantization; None: ideal sensors.
    rng : numpy.random.Generator
        Random numbers for the noise.
    solenoid : str
        Header ``solenoid``.

    Returns
    -------
    Recording
        With header ``coil_resistance_ohm`` (4-wire, before the run) and ``coil_temperature_C``.
    """
    n = truth.time_s.size
    u, i, f, x = truth.voltage_V.copy(), truth.current_A.copy(), truth.force_N.copy(), truth.position_m.copy()
    if exc.current_delay_s:
        i = np.interp(truth.time_s - exc.current_delay_s, truth.time_s, i)
    u = u + exc.voltage_offset_V
    if daq is not None:
        u = u + daq.voltage_offset_V + rng.normal(0.0, daq.voltage_noise_V, n)
        i = i + daq.current_offset_A + rng.normal(0.0, daq.current_noise_A, n)
        f = daq.force_gain * f + daq.force_offset_N + rng.normal(0.0, daq.force_noise_N, n)
        x = x + rng.normal(0.0, daq.position_noise_m, n)
        levels = 2.0 ** daq.adc_bits
        u = _quantize(np.clip(u, -daq.voltage_range_V, daq.voltage_range_V), 2 * daq.voltage_range_V / levels)
        i = _quantize(np.clip(i, -daq.current_range_A, daq.current_range_A), 2 * daq.current_range_A / levels)
        f = _quantize(np.clip(f, -daq.force_range_N, daq.force_range_N), 2 * daq.force_range_N / levels)
        x = _quantize(x, daq.position_resolution_m)
    header = {"coil_resistance_ohm": round(truth.resistance_start_ohm, 4),
              "coil_temperature_C": round(truth.temperature_start_C, 1),
              "sample_rate_Hz": exc.sample_rate_Hz, "notes": exc.notes}
    if exc.header_keys is not None:
        header = {k: (v if k in exc.header_keys else None) for k, v in header.items()}
    return make_recording(
        exc.kind, solenoid, truth.time_s, i,
        voltage_V=u if exc.with_voltage else None,
        force_N=f if exc.with_force else None,
        position_m=x if exc.position_column else float(exc.pos_m[0]), **header)
