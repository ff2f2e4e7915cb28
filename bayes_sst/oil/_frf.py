"""Frequency response of the table from broadband tests: the H1 estimate and its coherence.

For a command x (a_cmd preferred, else u_cmd) and the measured motion y (a, else u) of a
test, Welch-averaged spectra over Hann-windowed segments with 50 % overlap give

    H1(f) = S_xy(f)/S_xx(f),    gamma^2(f) = |S_xy|^2/(S_xx*S_yy),

S_xy = E[conj(X)*Y] (scipy.signal.csd's convention). H1 is unbiased by noise on the output,
which is where the twin and a real table put it (the command is known exactly). Tests of
the same payload are pooled by adding their segment-averaged spectra weighted by their
numbers of segments, i.e. one Welch average over all their segments.

Random error (Bendat & Piersol, Random Data, on frequency response estimates): the relative standard
deviation of |H1| (and the standard deviation of its phase, rad) is

    eps_r(f) = sqrt(1 - gamma^2)/(|gamma|*sqrt(2*n_d)),

with n_d the number of independent averages. Hann segments overlapping by half are not
independent; Welch's variance factor 1 + 2*rho^2 (rho the window's overlap correlation,
0.167 for Hann at 50 %) turns the segment count into n_d.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.signal import csd, get_window, welch

DEFAULT_SEGMENT_S = 2.0
DEFAULT_OVERLAP = 0.5
WINDOW = "hann"
# Command -> response pairs, best first: acceleration records the oil column directly.
SIGNAL_PAIRS = (("a_cmd", "a"), ("u_cmd", "u"))


@dataclass(frozen=True)
class FrequencyResponse:
    """A (pooled) H1 estimate on the one-sided frequency grid.

    frequency_hz, h (complex H1), coherence (gamma^2), s_xx, s_yy (auto-spectra) and s_xy
    (cross-spectrum, one-sided densities); n_segments: Welch segments averaged in all;
    n_independent: the equivalent number of independent averages n_d; input/output: the
    column names used; tests: ids of the tests pooled.
    """

    frequency_hz: np.ndarray
    h: np.ndarray
    coherence: np.ndarray
    s_xx: np.ndarray
    s_yy: np.ndarray
    s_xy: np.ndarray
    n_segments: int
    n_independent: float
    sample_rate_hz: float
    segment_samples: int
    input: str
    output: str
    tests: tuple[str, ...] = ()

    @property
    def magnitude(self) -> np.ndarray:
        return np.abs(self.h)

    @property
    def resolution_hz(self) -> float:
        return float(self.frequency_hz[1] - self.frequency_hz[0])

    def random_error(self) -> np.ndarray:
        """eps_r = sqrt(1 - gamma^2)/(|gamma|*sqrt(2*n_d)): relative sd of |H1| per bin (inf where gamma = 0)."""
        gamma2 = np.clip(self.coherence, 0.0, 1.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            eps = np.sqrt(1.0 - gamma2) / (np.sqrt(gamma2) * math.sqrt(2.0 * self.n_independent))
        return np.where(gamma2 > 0.0, eps, np.inf)


def overlap_variance_factor(segment_samples: int, overlap: float = DEFAULT_OVERLAP, window: str = WINDOW) -> float:
    """Welch's factor 1 + 2*sum_j rho_j^2 by which overlapping segments fall short of independent ones.

    rho_j = sum(w[n]*w[n + j*step])/sum(w^2) for the segments that overlap (Welch 1967).
    Returned for many segments, which is the case where it matters.
    """
    w = get_window(window, segment_samples)
    step = segment_samples - int(round(overlap * segment_samples))
    total = 0.0
    j = 1
    while j * step < segment_samples:
        rho = float(np.dot(w[: segment_samples - j * step], w[j * step:]) / np.dot(w, w))
        total += rho * rho
        j += 1
    return 1.0 + 2.0 * total


def segment_count(n: int, segment_samples: int, overlap_samples: int) -> int:
    """Segments scipy's Welch averages for n samples (no padding): 1 + (n - L)//(L - overlap)."""
    if n < segment_samples:
        return 0
    return 1 + (n - segment_samples) // (segment_samples - overlap_samples)


def _spectra(x, y, fs: float, segment_samples: int, overlap_samples: int):
    kwargs = dict(fs=fs, window=WINDOW, nperseg=segment_samples, noverlap=overlap_samples, detrend="constant")
    f, s_xx = welch(x, **kwargs)
    _, s_yy = welch(y, **kwargs)
    _, s_xy = csd(x, y, **kwargs)
    return f, s_xx, s_yy, s_xy


def has_command(record) -> bool:
    """Whether a test records a command beside its motion, one of SIGNAL_PAIRS ((a_cmd, a) or
    (u_cmd, u)), which a frequency response needs."""
    return any(all(record.get(name) is not None for name in pair) for pair in SIGNAL_PAIRS)


def common_signals(records) -> tuple[str, str]:
    """The best (input, output) column pair that every test records: (a_cmd, a), else (u_cmd, u)."""
    for pair in SIGNAL_PAIRS:
        if all(r.get(name) is not None for r in records for name in pair):
            return pair
    lacking = [r.id for r in records if not has_command(r)]
    raise ValueError("a frequency response needs a command and the measured motion, (a_cmd, a) or "
                     "(u_cmd, u), in every test; " + (f"tests {lacking} record neither" if lacking else
                     "the tests share neither pair"))


def frequency_response(
    records,
    *,
    segment_s: float = DEFAULT_SEGMENT_S,
    overlap: float = DEFAULT_OVERLAP,
    signals: tuple[str, str] | None = None,
) -> FrequencyResponse:
    """The pooled H1 estimate of one or more tests (TestRecord) of the same table configuration.

    segment_s: Welch segment length, s (resolution 1/segment_s Hz); overlap: fraction of a
    segment shared with the next. signals: the (input, output) column pair; by default the
    best pair every test records, (a_cmd, a) before (u_cmd, u).

    Tests recorded at different rates are pooled on the bins they share, up to the lowest
    Nyquist frequency: a segment of segment_s seconds gives every rate the same bin spacing
    1/segment_s, and the one-sided densities are per hertz whatever the rate. Rates for which
    segment_s*fs is not a whole number of samples have a different spacing and are refused.
    sample_rate_hz and segment_samples are then the lowest rate's.
    """
    records = list(records)
    if not records:
        raise ValueError("no tests to estimate a frequency response from")
    if not 0.0 <= overlap < 1.0:
        raise ValueError(f"overlap must lie in [0, 1), got {overlap!r}")
    if signals is None:
        signals = common_signals(records)
    ids = tuple(r.id for r in records)
    # the lowest rate first: its grid is the one every test shares (less its Nyquist bin where
    # the rates differ, which the one-sided density counts once at that rate and twice above it)
    records = sorted(records, key=lambda r: r.sample_rate_hz)
    mixed = len({round(r.sample_rate_hz, 6) for r in records}) > 1
    fs = float(records[0].sample_rate_hz)
    segment = int(round(segment_s * fs))
    if segment < 16:
        raise ValueError(f"a {segment_s} s segment holds only {segment} samples at {fs:g} Hz")
    spacing = fs / segment
    x_name, y_name = signals
    sums, f = None, None
    n_total = 0
    for record in records:
        rate = float(record.sample_rate_hz)
        samples = int(round(segment_s * rate))
        if abs(rate / samples - spacing) > 1e-9 * spacing:
            raise ValueError(f"tests pooled into one frequency response need the same bin spacing: a {segment_s} s "
                             f"segment gives {spacing:.6g} Hz at {fs:g} Hz but {rate / samples:.6g} Hz at {rate:g} Hz "
                             f"(test {record.id!r})")
        overlap_samples = int(round(overlap * samples))
        x = np.asarray(record.get(x_name), dtype=float)
        y = np.asarray(record.get(y_name), dtype=float)
        count = segment_count(len(x), samples, overlap_samples)
        if count == 0:
            raise ValueError(f"test {record.id!r} is {len(x) / rate:.3g} s long, shorter than one "
                             f"{segment_s} s segment")
        f_test, s_xx, s_yy, s_xy = _spectra(x, y, rate, samples, overlap_samples)
        if f is None:
            f = f_test[:-1] if mixed else f_test
        n = len(f)
        part = (count * s_xx[:n], count * s_yy[:n], count * s_xy[:n])
        sums = part if sums is None else tuple(a + b for a, b in zip(sums, part))
        n_total += count
    s_xx, s_yy, s_xy = (s / n_total for s in sums)
    with np.errstate(divide="ignore", invalid="ignore"):
        h = np.where(s_xx > 0.0, s_xy / s_xx, 0.0)
        coherence = np.where((s_xx > 0.0) & (s_yy > 0.0), np.abs(s_xy) ** 2 / (s_xx * s_yy), 0.0)
    n_independent = n_total / overlap_variance_factor(segment, overlap)
    return FrequencyResponse(
        frequency_hz=f,
        h=h,
        coherence=np.clip(coherence, 0.0, 1.0),
        s_xx=s_xx,
        s_yy=s_yy,
        s_xy=s_xy,
        n_segments=n_total,
        n_independent=float(n_total if n_total == 1 else max(1.0, n_independent)),
        sample_rate_hz=fs,
        segment_samples=segment,
        input=x_name,
        output=y_name,
        tests=ids,
    )


def bin_error_correlation(segment_samples: int, window: str = WINDOW, lags: int = 4) -> np.ndarray:
    """Correlation of the H1 errors of bins k and k + j, j = 0..lags: |rho_j|^2.

    rho_j = sum(w^2*exp(-2j*pi*j*n/N))/sum(w^2) is the correlation of a windowed segment's
    DFT values j bins apart for locally white signals; the H1 error at a bin is a product
    of the input's and the noise's DFT values, so its correlation is |rho_j|^2: 4/9, 1/36, 0
    for Hann.
    """
    w2 = get_window(window, segment_samples) ** 2
    n = np.arange(segment_samples)
    rho = np.array([np.sum(w2 * np.exp(-2j * np.pi * j * n / segment_samples)) for j in range(lags + 1)])
    return np.abs(rho / rho[0]) ** 2
