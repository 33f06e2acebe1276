//! Device clocks mapped onto the host clock, so that samples from several boards can be put on
//! one host timeline.
//!
//! Every sample frame carries `timestamp_us`, the device's clock in µs since it booted. That
//! clock runs from its own crystal (up to ±100 ppm off) and has its own origin. The host sees
//! each frame arrive at an instant of its monotonic clock, later than the sample was taken by a
//! positive, variable latency: USB polling (up to 1 ms), the device's queue, the operating
//! system's scheduler; mostly small, sometimes tens of ms, sometimes a stall after which
//! several frames arrive together.
//!
//! # Model
//!
//! For one device, `arrival_us = host(device_us) + latency_us` with `latency_us ≥ 0` and
//! `host(d) = a + b·d` a straight line over the tens of seconds the estimate looks at (a
//! crystal's frequency changes far less than 1 ppm over that time). So every point
//! `(device_us, arrival_us)` lies on or above the true line, and the points with the least
//! latency lie closest to it: the line is found from the **lower envelope** of the points, and
//! delayed frames, however many and by however much, do not move it as long as some frames
//! get through quickly.
//!
//! # Method
//!
//! 1. **Minimum-delay filter** (as NTP's clock filter trusts, of its recent exchanges, the one
//!    with the least delay): device time is cut into windows of
//!    [`ClockMapperConfig::window_us`] and each window keeps only its frame with the smallest
//!    `arrival_us − device_us`. A bounded number ([`WINDOW_CAPACITY`]) of recent windows is
//!    kept, so memory does not grow with the stream and the work per observation is bounded
//!    (each refit touches at most [`WINDOW_CAPACITY`]` + 1` points, and a refit happens only
//!    when a window closes or the open window's minimum improves).
//! 2. **Linear-programming fit** (S. B. Moon, P. Skelly, D. Towsley, "Estimation and removal of
//!    clock skew from network delay measurements", IEEE INFOCOM 1999): among the lines lying
//!    below every kept point, take the one minimising the summed vertical distance to the
//!    points. That objective is `Σ yᵢ − n·(a + b·x̄)`, so the optimum is the line supporting the
//!    lower convex hull of the points at their mean device time `x̄`: one edge of the hull,
//!    found in linear time with the monotone-chain hull. Unlike a least-squares fit it has no
//!    bias from the (one-sided, heavy-tailed) latency, and unlike the single lowest point it
//!    uses the whole history for the drift.
//! 3. **Not fresher than it is.** One-way timing cannot tell a clock offset from a constant
//!    latency: the envelope is the sampling instant *plus the smallest latency the link ever
//!    achieves*. The mapping therefore subtracts [`ClockMapperConfig::min_latency_bound_us`],
//!    an assumed upper bound on that smallest latency. While the assumption holds a mapped
//!    time is no later than the instant the sample was taken (up to the fit error counted in
//!    the uncertainty), so a sample never looks younger than it is; the price is that mapped
//!    times are early by up to that bound.
//!
//! # Uncertainty
//!
//! [`ClockEstimate::uncertainty_us`] is
//! `min_latency_bound_us + split_half_us + median_residual_us + 1`:
//!
//! - `min_latency_bound_us` covers the unknown smallest latency (above);
//! - `split_half_us` is the fit's own statistical error, measured by fitting the older and the
//!   newer half of the kept windows separately (same method) and taking the larger distance
//!   between a half's line and the whole fit at the newest device time;
//! - `median_residual_us`, the median height of the windows' minima above the fitted line,
//!   stands for how far even the lowest minima (those the line rests on) may lie above the
//!   smallest latency: with few frames per window no frame may have been that fast;
//! - 1 µs covers the rounding of the mapping.
//!
//! Away from the newest device time the uncertainty grows by
//! [`ClockEstimate::uncertainty_growth_ppm`] (the halves' largest slope difference plus the
//! assumed frequency wander [`ClockMapperConfig::wander_ppm`]), so an estimate used far from its
//! data says it is less sure. It bounds `|mapped − true sampling instant|` if the smallest
//! latency is below `min_latency_bound_us` and the fit is no further from the envelope than its
//! halves are from each other plus the median residual. One-way timing gives no bound without
//! some such assumption, so it is an estimate of the bound, not a guarantee.
//!
//! # Restarts
//!
//! [`ClockMapper::observe`] forgets everything and starts again from the new frame, telling so
//! with [`Observation::Restarted`] and [`ClockMapper::restarts`], when:
//!
//! - the device time goes back (the device rebooted): [`RestartReason::DeviceReboot`];
//! - the host time goes back (not a monotonic clock): [`RestartReason::HostClockBackwards`];
//! - either clock jumps forward by more than the kept history (the stream stopped for long):
//!   [`RestartReason::Gap`]; a shorter gap keeps the history, which ages out window by window;
//! - a frame arrives well before the line allows, which no latency explains, or the minima of
//!   [`ClockMapperConfig::step_windows`] consecutive windows lie well above it (the host clock
//!   stepped; a mere stall does not last that long): [`RestartReason::ClockStep`]. In the latter
//!   case those recent windows are kept.
//!
//! After a restart [`ClockMapper::to_host_us`] is `None` again until enough windows are seen.
//!
//! # Merging
//!
//! [`merge_by_host_time`] puts mapped samples of several devices on one timeline. Two samples
//! whose mapped times differ by less than the sum of their uncertainties have no reliable order
//! between them; the merge orders them by device index then, which is stable but arbitrary.

/// How many windows (minimum-delay points) one [`ClockMapper`] keeps at most.
pub const WINDOW_CAPACITY: usize = 64;

/// Windows needed (closed ones plus the open one) before there is an estimate: two for each of
/// the two halves the uncertainty compares.
const MIN_WINDOWS: usize = 4;

/// Settings of a [`ClockMapper`]. [`Default`] is meant for the pad's USB full-speed link.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClockMapperConfig {
    /// Length of one minimum-delay window in device µs (at least 1). Long enough to hold some
    /// frames at the lowest rate (12 at 25 sets per second for the default 500 ms), short
    /// enough that the drift inside one window (500 ppm × 500 ms = 250 µs at most) stays below
    /// [`Self::min_latency_bound_us`]. The kept history is [`WINDOW_CAPACITY`] windows.
    pub window_us: u64,
    /// Assumed upper bound, in µs, on the smallest latency the link achieves (the fixed part of
    /// the USB and operating-system path). Mapped times are moved this much earlier so they are
    /// never later than the true sampling instant; it is also the larger part of the reported
    /// uncertainty.
    pub min_latency_bound_us: u64,
    /// Largest believable difference of rate between device and host clocks, in ppm. A fit
    /// outside it is not used (there is no estimate then).
    pub max_drift_ppm: f64,
    /// How far, in µs beyond the uncertainty, a frame may arrive before the line, or window
    /// minima lie above it, before the host clock is taken to have stepped.
    pub step_threshold_us: u64,
    /// How many consecutive windows must lie above the line by more than
    /// [`Self::step_threshold_us`] to be a clock step rather than a stall (1 to
    /// [`WINDOW_CAPACITY`]).
    pub step_windows: usize,
    /// Assumed change of the clocks' rate difference, in ppm, added to the growth of the
    /// uncertainty away from the newest device time.
    pub wander_ppm: f64,
}

impl Default for ClockMapperConfig {
    fn default() -> Self {
        Self {
            window_us: 500_000,
            min_latency_bound_us: 500,
            max_drift_ppm: 500.0,
            step_threshold_us: 20_000,
            step_windows: 4,
            wander_ppm: 1.0,
        }
    }
}

impl ClockMapperConfig {
    /// The same settings with out-of-range values replaced: a zero window by 1, the step count
    /// clamped to 1..=[`WINDOW_CAPACITY`],
    /// a drift bound that is not a positive number (or above 10⁵ ppm) by the default, and a
    /// wander that is not a non-negative number by the default.
    fn sanitized(self) -> Self {
        let default = Self::default();
        Self {
            window_us: self.window_us.max(1),
            min_latency_bound_us: self.min_latency_bound_us,
            max_drift_ppm: if self.max_drift_ppm > 0.0 && self.max_drift_ppm <= 100_000.0 {
                self.max_drift_ppm
            } else {
                default.max_drift_ppm
            },
            step_threshold_us: self.step_threshold_us,
            step_windows: self.step_windows.clamp(1, WINDOW_CAPACITY),
            wander_ppm: if self.wander_ppm >= 0.0 && self.wander_ppm.is_finite() {
                self.wander_ppm
            } else {
                default.wander_ppm
            },
        }
    }

    /// Device µs of history kept: [`WINDOW_CAPACITY`] windows.
    fn history_us(&self) -> u64 {
        self.window_us.saturating_mul(WINDOW_CAPACITY as u64)
    }
}

/// What [`ClockMapper::observe`] did with a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Observation {
    /// The frame was added to the current estimate.
    Accepted,
    /// Everything before this frame was forgotten, for this reason; the frame starts the new
    /// estimate.
    Restarted(RestartReason),
}

/// Why a [`ClockMapper`] started again.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RestartReason {
    /// The device time went back: the device rebooted (its clock starts again from 0).
    DeviceReboot,
    /// The host time went back, which a monotonic clock never does.
    HostClockBackwards,
    /// A clock jumped forward by more than the kept history: the old windows say nothing about
    /// the new ones.
    Gap,
    /// Frames stopped fitting the line in a way no latency explains: a frame arrived well
    /// before it, or several windows in a row lay well above it.
    ClockStep,
}

/// One device's clock mapped onto the host clock, at one moment of the stream.
///
/// The mapping is linear and increasing: a later device time never maps before an earlier one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClockEstimate {
    /// The device time the figures below refer to: the newest one observed, µs.
    pub device_us: u64,
    /// `device_us` mapped onto the host clock, µs (saturated to the `u64` range).
    pub host_us: u64,
    /// Host time minus device time at `device_us`, µs (saturated to the `i64` range).
    pub offset_us: i64,
    /// How fast the device clock runs compared with the host clock, in ppm: positive when the
    /// device gains (its µs are shorter than the host's).
    pub drift_ppm: f64,
    /// Estimated bound on `|mapped − true sampling instant|` at `device_us`, µs; how it is made
    /// and what it assumes is in the [module documentation](self).
    pub uncertainty_us: u64,
    /// How much the uncertainty grows per second of device time away from `device_us`, in µs
    /// per second (ppm).
    pub uncertainty_growth_ppm: f64,
    // The unsaturated mapping: host µs at `device_us`, and host µs per device µs.
    host_reference_us: i128,
    host_per_device: f64,
}

impl ClockEstimate {
    /// `device_us` on the host clock, µs: extrapolated along the line, rounded down, saturated
    /// to the `u64` range. Non-decreasing in `device_us`.
    pub fn to_host_us(&self, device_us: u64) -> u64 {
        let device_delta_us = i128::from(device_us) - i128::from(self.device_us);
        // Rounding, flooring, the saturating float-to-integer cast and the clamp are each
        // non-decreasing, and the slope is positive, so the whole mapping is non-decreasing.
        let host_delta_us = (device_delta_us as f64 * self.host_per_device).floor() as i128;
        clamp_to_u64(self.host_reference_us.saturating_add(host_delta_us))
    }

    /// The uncertainty of [`Self::to_host_us`] at `device_us`: [`Self::uncertainty_us`] grown
    /// by [`Self::uncertainty_growth_ppm`] with the distance from [`Self::device_us`], µs.
    pub fn uncertainty_at_us(&self, device_us: u64) -> u64 {
        let distance_us = device_us.abs_diff(self.device_us) as f64;
        let growth_us = (distance_us * self.uncertainty_growth_ppm * 1e-6).ceil();
        // Saturating float-to-integer cast: an absurd distance gives u64::MAX, not a panic.
        self.uncertainty_us.saturating_add(growth_us as u64)
    }
}

/// One observation: a device time and a host time, µs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
struct Point {
    device_us: u64,
    host_us: u64,
}

impl Point {
    /// Host minus device time: the latency plus the (slowly drifting) offset, µs.
    fn apparent_offset_us(self) -> i128 {
        i128::from(self.host_us) - i128::from(self.device_us)
    }
}

/// A line through one of its points: `host = anchor.host_us + slope·(device − anchor.device_us)`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Line {
    anchor: Point,
    host_per_device: f64,
}

impl Line {
    /// The line at `device_us`, relative to the anchor's host time, µs.
    fn host_delta_us(&self, device_us: u64) -> f64 {
        (i128::from(device_us) - i128::from(self.anchor.device_us)) as f64 * self.host_per_device
    }

    /// How far `point` lies above the line, µs (negative: below).
    fn residual_us(&self, point: Point) -> f64 {
        let host_delta_us = (i128::from(point.host_us) - i128::from(self.anchor.host_us)) as f64;
        host_delta_us - self.host_delta_us(point.device_us)
    }

    /// `other` minus `self` at `device_us`, µs.
    fn difference_us(&self, other: &Line, device_us: u64) -> f64 {
        let anchors_us =
            (i128::from(other.anchor.host_us) - i128::from(self.anchor.host_us)) as f64;
        anchors_us + other.host_delta_us(device_us) - self.host_delta_us(device_us)
    }
}

/// The minimum-delay line of `points` (strictly increasing device times expected, anything
/// accepted): the lower-hull edge at the points' mean device time. `None` for fewer than two
/// distinct device times.
fn fit_lower_envelope(points: &[Point]) -> Option<Line> {
    let first = *points.first()?;
    // Coordinates relative to the first point: exact in f64 over any kept history.
    let relative = |point: Point| {
        (
            (i128::from(point.device_us) - i128::from(first.device_us)) as f64,
            (i128::from(point.host_us) - i128::from(first.host_us)) as f64,
        )
    };
    let mut hull = [(0.0_f64, 0.0_f64, Point::default()); WINDOW_CAPACITY + 1];
    let mut hull_len = 0_usize;
    let mut device_sum_us = 0.0_f64;
    let mut count = 0_usize;
    for &point in points.iter().take(hull.len()) {
        let (x, y) = relative(point);
        device_sum_us += x;
        count += 1;
        if hull_len > 0 {
            let (last_x, last_y, _) = hull[hull_len - 1];
            if x < last_x {
                // Out of order: the caller keeps device times increasing; skip rather than
                // build a wrong hull.
                continue;
            }
            if x == last_x {
                if y >= last_y {
                    continue;
                }
                hull_len -= 1;
            }
        }
        while hull_len >= 2 {
            let (ax, ay, _) = hull[hull_len - 2];
            let (bx, by, _) = hull[hull_len - 1];
            // Keep b only if a → b → point turns left (b lies strictly below the chord).
            let cross = (bx - ax) * (y - ay) - (by - ay) * (x - ax);
            if cross > 0.0 {
                break;
            }
            hull_len -= 1;
        }
        hull[hull_len] = (x, y, point);
        hull_len += 1;
    }
    if hull_len < 2 || count == 0 {
        return None;
    }
    let mean_x = device_sum_us / count as f64;
    let mut edge = 0;
    while edge + 2 < hull_len && hull[edge + 1].0 < mean_x {
        edge += 1;
    }
    let (ax, ay, anchor) = hull[edge];
    let (bx, by, _) = hull[edge + 1];
    let host_per_device = (by - ay) / (bx - ax);
    host_per_device.is_finite().then_some(Line {
        anchor,
        host_per_device,
    })
}

/// The whole fit and its two halves (for the uncertainty).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Fits {
    whole: Line,
    older_half: Line,
    newer_half: Line,
    median_residual_us: f64,
}

impl Fits {
    fn of(points: &[Point]) -> Option<Self> {
        if points.len() < MIN_WINDOWS {
            return None;
        }
        let (older, newer) = points.split_at(points.len() / 2);
        let whole = fit_lower_envelope(points)?;
        let mut residuals_us = [0.0_f64; WINDOW_CAPACITY + 1];
        let count = points.len().min(residuals_us.len());
        for (residual_us, &point) in residuals_us.iter_mut().zip(points) {
            *residual_us = whole.residual_us(point);
        }
        let (_, median_residual_us, _) =
            residuals_us[..count].select_nth_unstable_by(count / 2, f64::total_cmp);
        Some(Self {
            whole,
            older_half: fit_lower_envelope(older)?,
            newer_half: fit_lower_envelope(newer)?,
            median_residual_us: *median_residual_us,
        })
    }

    /// The halves' largest distance from the whole fit at `device_us`, µs.
    fn split_half_us(&self, device_us: u64) -> f64 {
        let older = self.whole.difference_us(&self.older_half, device_us).abs();
        let newer = self.whole.difference_us(&self.newer_half, device_us).abs();
        older.max(newer)
    }

    /// The halves' largest slope difference from the whole fit, ppm.
    fn split_half_slope_ppm(&self) -> f64 {
        let older = (self.older_half.host_per_device - self.whole.host_per_device).abs();
        let newer = (self.newer_half.host_per_device - self.whole.host_per_device).abs();
        older.max(newer) * 1e6
    }
}

/// The window being filled: where it started and its minimum-delay frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct OpenWindow {
    start_device_us: u64,
    minimum: Point,
}

/// One device's clock mapped onto the host clock from its frames' device timestamps and
/// arrival times; the method is in the [module documentation](self).
///
/// Fixed size (no allocation), constant work per observation on average, never panics.
#[derive(Debug, Clone)]
pub struct ClockMapper {
    config: ClockMapperConfig,
    // Closed windows' minima, oldest first.
    windows: [Point; WINDOW_CAPACITY],
    windows_len: usize,
    open: Option<OpenWindow>,
    last: Option<Point>,
    fits: Option<Fits>,
    windows_above: usize,
    restarts: u64,
    last_restart: Option<RestartReason>,
}

impl Default for ClockMapper {
    fn default() -> Self {
        Self::new()
    }
}

impl ClockMapper {
    /// A mapper with the [default settings](ClockMapperConfig::default), nothing observed.
    pub fn new() -> Self {
        Self::with_config(ClockMapperConfig::default())
    }

    /// A mapper with these settings (out-of-range values are replaced, see the fields).
    pub fn with_config(config: ClockMapperConfig) -> Self {
        Self {
            config: config.sanitized(),
            windows: [Point::default(); WINDOW_CAPACITY],
            windows_len: 0,
            open: None,
            last: None,
            fits: None,
            windows_above: 0,
            restarts: 0,
            last_restart: None,
        }
    }

    /// The settings in use.
    pub fn config(&self) -> ClockMapperConfig {
        self.config
    }

    /// Takes one frame: its device timestamp and the host (monotonic clock) instant it arrived,
    /// both µs. Says whether the frame restarted the estimate (see the
    /// [module documentation](self)); any input is accepted.
    pub fn observe(&mut self, device_us: u64, host_arrival_us: u64) -> Observation {
        let point = Point {
            device_us,
            host_us: host_arrival_us,
        };
        let Some(last) = self.last else {
            self.begin(point);
            return Observation::Accepted;
        };
        if device_us < last.device_us {
            return self.restart(RestartReason::DeviceReboot, point);
        }
        if host_arrival_us < last.host_us {
            return self.restart(RestartReason::HostClockBackwards, point);
        }
        let history_us = self.config.history_us();
        if device_us - last.device_us > history_us || host_arrival_us - last.host_us > history_us {
            return self.restart(RestartReason::Gap, point);
        }
        if let Some(fits) = self.plausible_fits() {
            // Latency is never negative: a frame well before the line means a clock moved.
            let allowed_us =
                self.config.step_threshold_us as f64 + self.split_half_bound_us(&fits, device_us);
            if fits.whole.residual_us(point) < -allowed_us {
                return self.restart(RestartReason::ClockStep, point);
            }
        }
        self.last = Some(point);
        let mut observation = Observation::Accepted;
        match self.open {
            Some(open) if device_us - open.start_device_us >= self.config.window_us => {
                observation = self.close_window(open.minimum);
                self.open = Some(OpenWindow {
                    start_device_us: device_us,
                    minimum: point,
                });
            }
            Some(open) if point.apparent_offset_us() < open.minimum.apparent_offset_us() => {
                self.open = Some(OpenWindow {
                    start_device_us: open.start_device_us,
                    minimum: point,
                });
            }
            Some(_) => return observation,
            None => {
                self.open = Some(OpenWindow {
                    start_device_us: device_us,
                    minimum: point,
                });
            }
        }
        self.refit();
        observation
    }

    /// `device_us` on the host clock, µs, with the current estimate ([`ClockEstimate::to_host_us`]):
    /// `None` until the mapper has seen [four windows](ClockMapperConfig::window_us) of frames
    /// since it was made or last restarted (about 1.5 s at the default 500 ms windows), and
    /// while the fit is not believable (its drift beyond [`ClockMapperConfig::max_drift_ppm`]).
    ///
    /// For a fixed estimate a later device time never maps earlier. Meant for device times of
    /// the current boot of the device; the mapping of a frame in the kept history is earlier
    /// than its arrival by at least `min_latency_bound_us` less the drift within one window.
    pub fn to_host_us(&self, device_us: u64) -> Option<u64> {
        self.estimate()
            .map(|estimate| estimate.to_host_us(device_us))
    }

    /// The current mapping at the newest device time observed, with its uncertainty; `None`
    /// when [`Self::to_host_us`] is.
    pub fn estimate(&self) -> Option<ClockEstimate> {
        let fits = self.plausible_fits()?;
        let last = self.last?;
        let line = fits.whole;
        let envelope_us = i128::from(line.anchor.host_us)
            .saturating_add(line.host_delta_us(last.device_us).floor() as i128);
        let host_reference_us =
            envelope_us.saturating_sub(i128::from(self.config.min_latency_bound_us));
        let host_us = clamp_to_u64(host_reference_us);
        let offset = host_reference_us - i128::from(last.device_us);
        let offset_us =
            i64::try_from(offset).unwrap_or(if offset < 0 { i64::MIN } else { i64::MAX });
        let uncertainty = self.config.min_latency_bound_us as f64
            + self.split_half_bound_us(&fits, last.device_us)
            + fits.median_residual_us.max(0.0)
            + 1.0;
        Some(ClockEstimate {
            device_us: last.device_us,
            host_us,
            offset_us,
            drift_ppm: (1.0 / line.host_per_device - 1.0) * 1e6,
            uncertainty_us: uncertainty.ceil() as u64,
            uncertainty_growth_ppm: fits.split_half_slope_ppm() + self.config.wander_ppm,
            host_reference_us,
            host_per_device: line.host_per_device,
        })
    }

    /// Device µs per host µs of the fitted line when it is refused as an implausible drift
    /// (beyond [`ClockMapperConfig::max_drift_ppm`]): why there is no estimate although there
    /// were frames enough (a device clock running at another rate than the host's, such as a
    /// simulated device at another speed that does not say so).
    pub fn refused_rate(&self) -> Option<f64> {
        let fits = self.fits?;
        self.plausible_fits()
            .is_none()
            .then_some(1.0 / fits.whole.host_per_device)
    }

    /// How many times the mapper started again (reboots, clock steps, gaps) since it was made.
    pub fn restarts(&self) -> u64 {
        self.restarts
    }

    /// Why the mapper last started again, if it ever did.
    pub fn last_restart(&self) -> Option<RestartReason> {
        self.last_restart
    }

    /// Forgets everything observed (the restart count stays), as after a reconnection.
    pub fn clear(&mut self) {
        self.windows_len = 0;
        self.open = None;
        self.last = None;
        self.fits = None;
        self.windows_above = 0;
    }

    fn begin(&mut self, point: Point) {
        self.clear();
        self.last = Some(point);
        self.open = Some(OpenWindow {
            start_device_us: point.device_us,
            minimum: point,
        });
    }

    fn restart(&mut self, reason: RestartReason, point: Point) -> Observation {
        self.begin(point);
        self.restarts = self.restarts.saturating_add(1);
        self.last_restart = Some(reason);
        Observation::Restarted(reason)
    }

    /// The fits if their drift is believable.
    fn plausible_fits(&self) -> Option<Fits> {
        let fits = self.fits?;
        let drift = (fits.whole.host_per_device - 1.0).abs() * 1e6;
        (drift <= self.config.max_drift_ppm).then_some(fits)
    }

    /// Split-half disagreement at `device_us` grown with the distance from the newest device
    /// time (a bound of the disagreement at `device_us` for straight lines), plus the wander.
    fn split_half_bound_us(&self, fits: &Fits, device_us: u64) -> f64 {
        let newest_us = self.last.map_or(device_us, |last| last.device_us);
        let distance_us = device_us.abs_diff(newest_us) as f64;
        fits.split_half_us(newest_us)
            + distance_us * (fits.split_half_slope_ppm() + self.config.wander_ppm) * 1e-6
    }

    /// Adds a closed window's minimum to the history; may find a clock step.
    fn close_window(&mut self, minimum: Point) -> Observation {
        let above = fit_lower_envelope(&self.windows[..self.windows_len]).is_some_and(|line| {
            let allowed_us = self.config.step_threshold_us as f64
                + self.plausible_fits().map_or(0.0, |fits| {
                    self.split_half_bound_us(&fits, minimum.device_us)
                });
            line.residual_us(minimum) > allowed_us
        });
        self.windows_above = if above { self.windows_above + 1 } else { 0 };
        let history_us = self.config.history_us();
        let mut keep_from = 0;
        while keep_from < self.windows_len
            && minimum
                .device_us
                .saturating_sub(self.windows[keep_from].device_us)
                > history_us
        {
            keep_from += 1;
        }
        if self.windows_len - keep_from >= WINDOW_CAPACITY {
            keep_from = self.windows_len + 1 - WINDOW_CAPACITY;
        }
        self.windows.copy_within(keep_from..self.windows_len, 0);
        self.windows_len -= keep_from;
        self.windows[self.windows_len] = minimum;
        self.windows_len += 1;
        if self.windows_above < self.config.step_windows {
            return Observation::Accepted;
        }
        // The host clock moved: keep only the windows after the step.
        let kept = self.windows_above.min(self.windows_len);
        self.windows
            .copy_within(self.windows_len - kept..self.windows_len, 0);
        self.windows_len = kept;
        self.windows_above = 0;
        self.restarts = self.restarts.saturating_add(1);
        self.last_restart = Some(RestartReason::ClockStep);
        Observation::Restarted(RestartReason::ClockStep)
    }

    fn refit(&mut self) {
        let mut points = [Point::default(); WINDOW_CAPACITY + 1];
        points[..self.windows_len].copy_from_slice(&self.windows[..self.windows_len]);
        let mut len = self.windows_len;
        if let Some(open) = self.open {
            points[len] = open.minimum;
            len += 1;
        }
        self.fits = Fits::of(&points[..len]);
    }
}

fn clamp_to_u64(value: i128) -> u64 {
    u64::try_from(value.max(0)).unwrap_or(u64::MAX)
}

/// One sample on the merged timeline.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MergedSample<T> {
    /// Index of the device (its position in the input).
    pub device: usize,
    /// The sample's mapped host time, µs.
    pub host_us: u64,
    /// The sample itself.
    pub sample: T,
}

/// Puts several devices' samples, each with its mapped host time in µs (from that device's
/// [`ClockMapper`]), on one timeline: ordered by host time, equal times by device index, and
/// each device's samples with equal times in their given order.
///
/// Samples closer than the sum of their uncertainties may be in either order in truth.
pub fn merge_by_host_time<T>(devices: Vec<Vec<(u64, T)>>) -> Vec<MergedSample<T>> {
    let mut merged: Vec<MergedSample<T>> = devices
        .into_iter()
        .enumerate()
        .flat_map(|(device, samples)| {
            samples
                .into_iter()
                .map(move |(host_us, sample)| MergedSample {
                    device,
                    host_us,
                    sample,
                })
        })
        .collect();
    // Stable: the given order survives among equal keys.
    merged.sort_by_key(|sample| (sample.host_us, sample.device));
    merged
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(device_us: u64, host_us: u64) -> Point {
        Point { device_us, host_us }
    }

    #[test]
    fn the_fit_is_the_hull_edge_under_the_mean_device_time() {
        // Lower hull: (0,10) (10,12) (20,14) on a slope of 0.2; the others lie above.
        let points = [
            point(0, 10),
            point(5, 30),
            point(10, 12),
            point(15, 40),
            point(20, 14),
        ];
        let line = fit_lower_envelope(&points).unwrap();
        assert!((line.host_per_device - 0.2).abs() < 1e-12);
        for &p in &points {
            assert!(line.residual_us(p) >= -1e-9, "{p:?}");
        }
    }

    #[test]
    fn one_point_or_one_device_time_gives_no_line() {
        assert_eq!(fit_lower_envelope(&[]), None);
        assert_eq!(fit_lower_envelope(&[point(3, 4)]), None);
        assert_eq!(fit_lower_envelope(&[point(3, 4), point(3, 2)]), None);
    }

    #[test]
    fn out_of_order_points_do_not_panic() {
        let points = [
            point(10, 10),
            point(0, 0),
            point(20, 20),
            point(u64::MAX, 0),
        ];
        let line = fit_lower_envelope(&points).unwrap();
        assert!(line.host_per_device.is_finite());
    }

    #[test]
    fn a_clock_at_another_rate_is_refused_and_its_rate_said() {
        let mut mapper = ClockMapper::new();
        for index in 0..400u64 {
            let host_us = 10_000 * index + 1_000;
            mapper.observe(5 * 10_000 * index, host_us);
        }
        assert!(mapper.estimate().is_none());
        let rate = mapper.refused_rate().unwrap();
        assert!((rate - 5.0).abs() < 0.01, "{rate}");
    }

    #[test]
    fn no_estimate_before_four_windows() {
        let mut mapper = ClockMapper::new();
        for device_us in (0..1_400_000).step_by(10_000) {
            mapper.observe(device_us, device_us + 1_000);
        }
        assert_eq!(mapper.to_host_us(0), None);
        for device_us in (1_400_000..2_000_000).step_by(10_000) {
            mapper.observe(device_us, device_us + 1_000);
        }
        assert!(mapper.to_host_us(0).is_some());
    }

    #[test]
    fn an_exact_clock_maps_to_arrival_less_the_latency_bound() {
        let mut mapper = ClockMapper::new();
        for device_us in (0..5_000_000).step_by(10_000) {
            mapper.observe(device_us, device_us + 7_000);
        }
        let estimate = mapper.estimate().unwrap();
        assert_eq!(estimate.to_host_us(1_000_000), 1_000_000 + 7_000 - 500);
        assert_eq!(estimate.offset_us, 7_000 - 500);
        assert!(estimate.drift_ppm.abs() < 1e-6);
        assert_eq!(estimate.uncertainty_us, 501);
        assert_eq!(
            estimate.uncertainty_at_us(estimate.device_us + 1_000_000),
            502
        );
    }

    #[test]
    fn the_estimate_saturates_at_the_extremes() {
        let mut mapper = ClockMapper::new();
        for step in 0..100_u64 {
            mapper.observe(u64::MAX - 10_000_000 + step * 100_000, step * 100_000);
        }
        let estimate = mapper.estimate().unwrap();
        assert_eq!(estimate.to_host_us(0), 0);
        assert!(estimate.offset_us < 0);
        assert!(estimate.to_host_us(u64::MAX) <= 10_000_000);
    }

    #[test]
    fn merge_orders_by_host_time_then_device() {
        let merged = merge_by_host_time(vec![vec![(5, 'a'), (9, 'b')], vec![(5, 'c'), (7, 'd')]]);
        let order: Vec<char> = merged.iter().map(|sample| sample.sample).collect();
        assert_eq!(order, ['a', 'c', 'd', 'b']);
        assert_eq!(merged[1].device, 1);
    }
}
