//! `taxel plot`: pictures of a recording (pressure per taxel over time) or of a calibration
//! (the curve per taxel with its points, and each tier's residuals on reference loads), as SVG
//! or PNG chosen by the output file's extension.
//!
//! Text is drawn with a font embedded in the binary (DejaVu Sans, see `assets/`), registered with
//! plotters' `ab_glyph` renderer, so PNG plots need no system fonts; SVG text is written as
//! `<text>` elements and rendered by the viewer.

use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context};
use model_core::{Calibration, TaxelInverses, Tier, TAXEL_COUNT};
use plotters::coord::Shift;
use plotters::prelude::*;

use taxel_host::calibrate::{read_loads, reference_data, ReferenceData};
use taxel_host::csv_format::TAXEL_LABELS;
use taxel_host::noteln;
use taxel_host::output_file::PendingRename;
use taxel_host::schema::{RowReader, SchemaError};
pub use taxel_plot_style::{register_embedded_font, tier_colour, TAXEL_COLOURS};

/// The long help of the subcommand.
pub const LONG_ABOUT: &str = "Plot to SVG or PNG (chosen by the output file's extension).\n\n\
`taxel plot recording.csv -o p.svg`: pressure per taxel over time, one panel per pad of each \
device, from a recording or a `taxel convert` output (the recording schema; time from the first \
row's host_time_s; empty cells are gaps).\n\n\
`taxel plot --calibration cal.json -o c.png [--loads loads.csv]`: the curve (dC/C0 against \
pressure) of each taxel with its points; with --loads, the measured rows on the curves and each \
tier's residual (predicted - applied pressure) per row.\n\n\
Rows that cannot be read are skipped and listed; a \
long recording is drawn as the lowest and highest value of each of 10 000 time buckets per \
taxel, so every peak shows and the work stays bounded. The image is written under a temporary \
name and renamed when complete. Text uses a font built into the tool, so no system fonts are \
needed.\n\n\
Examples:\n  taxel plot rec.csv -o rec.png\n  taxel plot --calibration cal.json --loads loads.csv -o \
cal.svg";

/// Arguments of `taxel plot`.
#[derive(Debug, Clone, clap::Args)]
pub struct PlotArgs {
    /// Recording or converted CSV to plot.
    #[arg(
        value_name = "CSV",
        required_unless_present = "calibration",
        conflicts_with = "calibration"
    )]
    pub input: Option<PathBuf>,
    /// Calibration file to plot instead of a recording.
    #[arg(long, value_name = "FILE")]
    pub calibration: Option<PathBuf>,
    /// Reference-load CSV (as for `taxel calibrate`) whose residuals to show.
    #[arg(long, value_name = "FILE", requires = "calibration")]
    pub loads: Option<PathBuf>,
    /// Image to write: .svg or .png.
    #[arg(short, long, value_name = "FILE")]
    pub output: PathBuf,
    /// Image width in pixels.
    #[arg(long, value_name = "PX")]
    pub width: Option<u32>,
    /// Image height in pixels.
    #[arg(long, value_name = "PX")]
    pub height: Option<u32>,
}

/// Image formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImageFormat {
    /// Scalable vector graphics.
    Svg,
    /// Portable network graphics.
    Png,
}

/// The format named by a file's extension.
pub fn image_format(path: &Path) -> anyhow::Result<ImageFormat> {
    let extension = path
        .extension()
        .and_then(|extension| extension.to_str())
        .map(str::to_ascii_lowercase);
    match extension.as_deref() {
        Some("svg") => Ok(ImageFormat::Svg),
        Some("png") => Ok(ImageFormat::Png),
        _ => bail!("{}: the output must end in .svg or .png", path.display()),
    }
}

/// The most points drawn per taxel: longer recordings are reduced to the lowest and highest
/// value of each of this many time buckets, which keeps every peak and bounds the work.
pub const MAX_POINTS_PER_TAXEL: usize = 20_000;

/// The largest pressure drawn, kPa; anything beyond is not a measurement and is a gap.
const MAX_PLOTTED_KPA: f64 = 1.0e6;

/// One pad's pressures over time.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PadSeries {
    /// The device.
    pub device: u32,
    /// The pad of the device.
    pub pad: u8,
    /// Time of each row, s since the recording's first row.
    pub time_s: Vec<f64>,
    /// Pressure per taxel per row, kPa (`None` = empty cell: faulted, or the frame is missing).
    pub pressures_kpa: [Vec<Option<f64>>; TAXEL_COUNT],
}

/// Every pad's pressures over time, from a recording.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PressureSeries {
    /// Each pad of each device, in (device, pad) order.
    pub pads: Vec<PadSeries>,
    /// Rows read.
    pub rows: usize,
    /// Rows skipped because they could not be read: line number and reason.
    pub skipped_rows: Vec<(u64, String)>,
}

/// Reads every pad's pressures from a recording (or a `taxel convert` output) of the recording
/// schema, timed from its first row's host time. A row that cannot be read is skipped and
/// listed with its line number.
pub fn read_pressure_series<R: Read>(input: R) -> anyhow::Result<PressureSeries> {
    let mut reader = RowReader::new(BufReader::new(input))?;
    let mut pads: std::collections::BTreeMap<(u32, u8), PadSeries> = Default::default();
    let mut series = PressureSeries::default();
    let mut first_us = None;
    while let Some(row) = reader.next_row() {
        let row = match row {
            Ok(row) => row,
            Err(SchemaError::Row { line, reason }) => {
                series.skipped_rows.push((line, reason));
                continue;
            }
            Err(error) => return Err(error.into()),
        };
        series.rows += 1;
        let origin_us = *first_us.get_or_insert(row.host_time_us);
        let pad = pads
            .entry((row.device, row.pad))
            .or_insert_with(|| PadSeries {
                device: row.device,
                pad: row.pad,
                ..PadSeries::default()
            });
        pad.time_s
            .push((row.host_time_us as f64 - origin_us as f64) / 1e6);
        for taxel in 0..TAXEL_COUNT {
            let pressure = row
                .reading
                .as_ref()
                .and_then(|reading| reading.pressure_kpa[taxel])
                .map(f64::from)
                .filter(|value| value.is_finite() && value.abs() <= MAX_PLOTTED_KPA);
            pad.pressures_kpa[taxel].push(pressure);
        }
    }
    if series.rows == 0 {
        bail!("no readable row: nothing to plot");
    }
    series.pads = pads.into_values().collect();
    Ok(series)
}

/// At most [`MAX_POINTS_PER_TAXEL`] points of one taxel, in time order: all of them when they
/// are fewer, else the lowest and highest value of each time bucket (a gap stays a gap).
fn reduced(time_s: &[f64], values: &[Option<f64>]) -> (Vec<f64>, Vec<Option<f64>>) {
    if time_s.len() <= MAX_POINTS_PER_TAXEL {
        return (time_s.to_vec(), values.to_vec());
    }
    let bucket_len = time_s.len().div_ceil(MAX_POINTS_PER_TAXEL / 2);
    let mut reduced_time = Vec::with_capacity(MAX_POINTS_PER_TAXEL);
    let mut reduced_values = Vec::with_capacity(MAX_POINTS_PER_TAXEL);
    for (times, bucket) in time_s.chunks(bucket_len).zip(values.chunks(bucket_len)) {
        let present = bucket
            .iter()
            .zip(times)
            .filter_map(|(value, time)| value.map(|value| (*time, value)));
        let lowest = present.clone().min_by(|a, b| a.1.total_cmp(&b.1));
        let highest = present.max_by(|a, b| a.1.total_cmp(&b.1));
        match (lowest, highest) {
            (Some(lowest), Some(highest)) => {
                let (first, second) = if lowest.0 <= highest.0 {
                    (lowest, highest)
                } else {
                    (highest, lowest)
                };
                for (time, value) in [first, second] {
                    reduced_time.push(time);
                    reduced_values.push(Some(value));
                }
            }
            _ => {
                if let Some(time) = times.first() {
                    reduced_time.push(*time);
                    reduced_values.push(None);
                }
            }
        }
    }
    (reduced_time, reduced_values)
}

/// Runs of consecutive present values: each a line segment.
fn segments(time_s: &[f64], values: &[Option<f64>]) -> Vec<Vec<(f64, f64)>> {
    let mut runs = Vec::new();
    let mut current = Vec::new();
    for (time, value) in time_s.iter().zip(values) {
        match value {
            Some(value) => current.push((*time, *value)),
            None if !current.is_empty() => runs.push(std::mem::take(&mut current)),
            None => {}
        }
    }
    if !current.is_empty() {
        runs.push(current);
    }
    runs
}

fn padded_range(minimum: f64, maximum: f64) -> std::ops::Range<f64> {
    if !(maximum > minimum) {
        minimum - 0.5..minimum + 0.5
    } else {
        minimum..maximum
    }
}

type DrawResult<DB> = Result<(), DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

fn draw_pressures<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    series: &PressureSeries,
) -> DrawResult<DB> {
    root.fill(&WHITE)?;
    let areas = root.split_evenly((series.pads.len().max(1), 1));
    for (area, pad) in areas.iter().zip(&series.pads) {
        let caption = if series.pads.len() == 1 {
            "Pressure per taxel".to_owned()
        } else {
            format!("Device {} pad {}: pressure per taxel", pad.device, pad.pad)
        };
        draw_pad_pressures(area, pad, &caption)?;
    }
    Ok(())
}

fn draw_pad_pressures<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    series: &PadSeries,
    caption: &str,
) -> DrawResult<DB> {
    let time_min = series.time_s.iter().copied().fold(f64::INFINITY, f64::min);
    let time_max = series
        .time_s
        .iter()
        .copied()
        .fold(f64::NEG_INFINITY, f64::max);
    let time_range = if series.time_s.is_empty() {
        0.0..1.0
    } else {
        padded_range(time_min, time_max)
    };
    let pressure_max = series
        .pressures_kpa
        .iter()
        .flatten()
        .flatten()
        .copied()
        .fold(0.0, f64::max);
    let pressure_top = if pressure_max > 0.0 {
        pressure_max * 1.05
    } else {
        1.0
    };
    let mut chart = ChartBuilder::on(root)
        .caption(caption, ("sans-serif", 24))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(time_range, 0.0..pressure_top)?;
    chart
        .configure_mesh()
        .x_desc("time (s)")
        .y_desc("pressure (kPa)")
        .draw()?;
    for (taxel, values) in series.pressures_kpa.iter().enumerate() {
        let colour = TAXEL_COLOURS[taxel];
        let mut labelled = false;
        let (time_s, values) = reduced(&series.time_s, values);
        for run in segments(&time_s, &values) {
            let annotation = if run.len() == 1 {
                chart.draw_series(
                    run.iter()
                        .map(|point| Circle::new(*point, 2, colour.filled())),
                )?
            } else {
                chart.draw_series(LineSeries::new(run, colour.stroke_width(2)))?
            };
            if !labelled {
                annotation.label(TAXEL_LABELS[taxel]).legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
                });
                labelled = true;
            }
        }
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()?;
    Ok(())
}

/// One taxel's curve and, with reference loads, its rows and residuals.
struct TaxelPicture {
    inverses: TaxelInverses,
    points: Vec<(f64, f64)>,
    top_pressure_kpa: f64,
    top_relative_change: f64,
    measured: Vec<(f64, f64)>,
    residuals: Vec<(Tier, Vec<(f64, f64)>)>,
}

fn taxel_pictures(calibration: &Calibration, loads: Option<&ReferenceData>) -> Vec<TaxelPicture> {
    calibration
        .taxels()
        .iter()
        .enumerate()
        .map(|(taxel, taxel_calibration)| {
            let curve = taxel_calibration.curve();
            let inverses = TaxelInverses::new(curve);
            let top = curve.top();
            let measured: Vec<(f64, f64)> = loads
                .map(|data| {
                    data.rows
                        .iter()
                        .map(|row| (row.pressure_kpa, row.relative_change[taxel]))
                        .collect()
                })
                .unwrap_or_default();
            let residuals = if loads.is_some() {
                Tier::ALL
                    .iter()
                    .filter(|tier| inverses.supports(**tier))
                    .map(|&tier| {
                        let values = measured
                            .iter()
                            .map(|&(pressure_kpa, relative_change)| {
                                let within =
                                    (relative_change as f32).clamp(0.0, top.relative_change);
                                let predicted = f64::from(inverses.pressure_kpa(tier, within));
                                (pressure_kpa, predicted - pressure_kpa)
                            })
                            .collect();
                        (tier, values)
                    })
                    .collect()
            } else {
                Vec::new()
            };
            TaxelPicture {
                points: curve
                    .points()
                    .iter()
                    .map(|point| {
                        (
                            f64::from(point.pressure_kpa),
                            f64::from(point.relative_change),
                        )
                    })
                    .collect(),
                top_pressure_kpa: f64::from(top.pressure_kpa),
                top_relative_change: f64::from(top.relative_change),
                inverses,
                measured,
                residuals,
            }
        })
        .collect()
}

fn draw_curve<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    label: &str,
    picture: &TaxelPicture,
) -> DrawResult<DB> {
    let measured_max = picture
        .measured
        .iter()
        .map(|(_, relative_change)| *relative_change)
        .fold(picture.top_relative_change, f64::max);
    let measured_min = picture
        .measured
        .iter()
        .map(|(_, relative_change)| *relative_change)
        .fold(0.0, f64::min);
    let x_top = picture.top_pressure_kpa * 1.05;
    let mut chart = ChartBuilder::on(area)
        .caption(
            format!("{label}: dC/C0 against pressure"),
            ("sans-serif", 18),
        )
        .margin(8)
        .x_label_area_size(36)
        .y_label_area_size(56)
        .build_cartesian_2d(0.0..x_top, measured_min.min(0.0)..measured_max * 1.08)?;
    chart
        .configure_mesh()
        .x_desc("pressure (kPa)")
        .y_desc("dC/C0")
        .draw()?;
    let steps = 200;
    let curve = (0..=steps).map(|step| {
        let pressure_kpa = picture.top_pressure_kpa * f64::from(step) / f64::from(steps);
        (
            pressure_kpa,
            f64::from(picture.inverses.relative_change_at(pressure_kpa as f32)),
        )
    });
    chart
        .draw_series(LineSeries::new(curve, BLACK.stroke_width(2)))?
        .label("reference curve (monotone cubic)")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(2)));
    if !picture.measured.is_empty() {
        chart
            .draw_series(
                picture
                    .measured
                    .iter()
                    .map(|point| Cross::new(*point, 3, TAXEL_COLOURS[1].stroke_width(1))),
            )?
            .label("measured rows")
            .legend(|(x, y)| Cross::new((x + 10, y), 3, TAXEL_COLOURS[1].stroke_width(1)));
    }
    chart
        .draw_series(
            picture
                .points
                .iter()
                .map(|point| Circle::new(*point, 4, TAXEL_COLOURS[0].filled())),
        )?
        .label("calibration points")
        .legend(|(x, y)| Circle::new((x + 10, y), 4, TAXEL_COLOURS[0].filled()));
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::LowerRight)
        .draw()?;
    Ok(())
}

fn draw_residuals<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    label: &str,
    picture: &TaxelPicture,
) -> DrawResult<DB> {
    let largest = picture
        .residuals
        .iter()
        .flat_map(|(_, values)| values.iter().map(|(_, residual)| residual.abs()))
        .fold(0.0, f64::max);
    let half_range = if largest > 0.0 { largest * 1.15 } else { 0.1 };
    let x_top = picture.top_pressure_kpa * 1.05;
    let mut chart = ChartBuilder::on(area)
        .caption(
            format!("{label}: residual per tier (predicted - applied)"),
            ("sans-serif", 18),
        )
        .margin(8)
        .x_label_area_size(36)
        .y_label_area_size(56)
        .build_cartesian_2d(-0.02 * x_top..x_top, -half_range..half_range)?;
    chart
        .configure_mesh()
        .x_desc("applied pressure (kPa)")
        .y_desc("residual (kPa)")
        .draw()?;
    chart.draw_series(LineSeries::new(
        [(-0.02 * x_top, 0.0), (x_top, 0.0)],
        BLACK.stroke_width(1),
    ))?;
    let tier_count = picture.residuals.len().max(1) as f64;
    for (index, (tier, values)) in picture.residuals.iter().enumerate() {
        let colour = tier_colour(*tier);
        // A small sideways offset per tier keeps coincident residuals visible.
        let offset = (index as f64 - (tier_count - 1.0) / 2.0) * 0.006 * x_top;
        chart
            .draw_series(
                values
                    .iter()
                    .map(move |(x, y)| Circle::new((x + offset, *y), 3, colour.filled())),
            )?
            .label(tier.name())
            .legend(move |(x, y)| Circle::new((x + 10, y), 3, colour.filled()));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperLeft)
        .draw()?;
    Ok(())
}

fn draw_calibration<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    pictures: &[TaxelPicture],
    with_residuals: bool,
) -> DrawResult<DB> {
    root.fill(&WHITE)?;
    let (curve_area, residual_area) = if with_residuals {
        let (upper, lower) = root.split_vertically(root.dim_in_pixel().1 / 2);
        (upper, Some(lower))
    } else {
        (root.clone(), None)
    };
    for ((area, picture), label) in curve_area
        .split_evenly((2, 2))
        .iter()
        .zip(pictures)
        .zip(TAXEL_LABELS)
    {
        draw_curve(area, label, picture)?;
    }
    if let Some(residual_area) = residual_area {
        for ((area, picture), label) in residual_area
            .split_evenly((2, 2))
            .iter()
            .zip(pictures)
            .zip(TAXEL_LABELS)
        {
            draw_residuals(area, label, picture)?;
        }
    }
    Ok(())
}

fn drawing_error<E: std::error::Error + Send + Sync>(
    error: DrawingAreaErrorKind<E>,
) -> anyhow::Error {
    anyhow::anyhow!("drawing failed: {error}")
}

/// Draws with `draw` into an SVG or PNG file chosen by the extension of `path`.
/// The picture goes to a temporary file beside the target (same extension) that replaces the
/// target only once it is complete.
macro_rules! render_to_file {
    ($path:expr, $size:expr, |$root:ident| $draw:expr) => {{
        register_embedded_font()?;
        let format = image_format($path)?;
        let pending = PendingRename::beside($path)?;
        {
            let temporary = pending.path();
            match format {
                ImageFormat::Svg => {
                    let $root = SVGBackend::new(temporary, $size).into_drawing_area();
                    $draw.map_err(drawing_error)?;
                    $root.present().map_err(drawing_error)?;
                }
                ImageFormat::Png => {
                    let $root = BitMapBackend::new(temporary, $size).into_drawing_area();
                    $draw.map_err(drawing_error)?;
                    $root.present().map_err(drawing_error)?;
                }
            }
        }
        pending.commit()
    }};
}

/// Plots pressures over time to an SVG or PNG file.
pub fn plot_pressures(
    series: &PressureSeries,
    path: &Path,
    size: (u32, u32),
) -> anyhow::Result<()> {
    render_to_file!(path, size, |root| draw_pressures(&root, series))
}

/// Draws pressures over time as SVG text: what `plot` writes to a `.svg` file (for tests and
/// fuzzing, without a file).
pub fn pressures_svg(series: &PressureSeries, size: (u32, u32)) -> anyhow::Result<String> {
    register_embedded_font()?;
    let mut text = String::new();
    {
        let root = SVGBackend::with_string(&mut text, size).into_drawing_area();
        draw_pressures(&root, series).map_err(drawing_error)?;
        root.present().map_err(drawing_error)?;
    }
    Ok(text)
}

/// Plots a calibration's curves (and with reference loads, their rows and residuals per tier)
/// to an SVG or PNG file.
pub fn plot_calibration(
    calibration: &Calibration,
    loads: Option<&ReferenceData>,
    path: &Path,
    size: (u32, u32),
) -> anyhow::Result<()> {
    let pictures = taxel_pictures(calibration, loads);
    render_to_file!(path, size, |root| draw_calibration(
        &root,
        &pictures,
        loads.is_some()
    ))
}

/// Runs `taxel plot`.
pub fn run(args: &PlotArgs) -> anyhow::Result<ExitCode> {
    image_format(&args.output)?;
    match (&args.input, &args.calibration) {
        (Some(input), None) => {
            taxel_host::output_file::refuse_same_file(input, &args.output)?;
            if input.is_dir() {
                bail!("{} is a directory, not a file", input.display());
            }
            let file = File::open(input).with_context(|| format!("opening {}", input.display()))?;
            let series = read_pressure_series(BufReader::new(file))
                .with_context(|| format!("reading {}", input.display()))?;
            for (line, reason) in series.skipped_rows.iter().take(10) {
                noteln!("line {line}: skipped: {reason}");
            }
            if series.skipped_rows.len() > 10 {
                noteln!(
                    "... and {} more skipped rows",
                    series.skipped_rows.len() - 10
                );
            }
            let panels = u32::try_from(series.pads.len().max(1)).unwrap_or(u32::MAX);
            let size = (
                args.width.unwrap_or(1200),
                args.height
                    .unwrap_or(600_u32.saturating_mul(panels.min(4)).max(600)),
            );
            plot_pressures(&series, &args.output, size)?;
            let longest = series
                .pads
                .iter()
                .map(|pad| pad.time_s.len())
                .max()
                .unwrap_or(0);
            noteln!(
                "wrote {} ({} rows, {} pad(s){})",
                args.output.display(),
                series.rows,
                series.pads.len(),
                if longest > MAX_POINTS_PER_TAXEL {
                    format!(
                        "; drawn as the low and high of {} time buckets per taxel",
                        MAX_POINTS_PER_TAXEL / 2
                    )
                } else {
                    String::new()
                }
            );
        }
        (None, Some(calibration_path)) => {
            let calibration = taxel_host::calibration_file::read(calibration_path)
                .with_context(|| format!("reading {}", calibration_path.display()))?;
            let loads = match &args.loads {
                Some(loads_path) => {
                    let file = File::open(loads_path)
                        .with_context(|| format!("opening {}", loads_path.display()))?;
                    let rows = read_loads(BufReader::new(file))
                        .with_context(|| format!("reading {}", loads_path.display()))?;
                    let parasitic_pf: [f64; TAXEL_COUNT] = std::array::from_fn(|taxel| {
                        f64::from(calibration.taxels()[taxel].parasitic_pf())
                    });
                    Some(reference_data(
                        &rows,
                        parasitic_pf,
                        calibration.temperature_law(),
                    )?)
                }
                None => None,
            };
            let default_height = if loads.is_some() { 1400 } else { 800 };
            let size = (
                args.width.unwrap_or(1200),
                args.height.unwrap_or(default_height),
            );
            plot_calibration(&calibration, loads.as_ref(), &args.output, size)?;
            noteln!("wrote {}", args.output.display());
        }
        _ => bail!("give a CSV file, or --calibration FILE"),
    }
    Ok(ExitCode::SUCCESS)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gaps_split_the_line() {
        let time_s = [0.0, 1.0, 2.0, 3.0, 4.0];
        let values = [Some(1.0), Some(2.0), None, Some(3.0), None];
        let runs = segments(&time_s, &values);
        assert_eq!(runs, vec![vec![(0.0, 1.0), (1.0, 2.0)], vec![(3.0, 3.0)]]);
    }

    #[test]
    fn format_follows_the_extension() {
        assert_eq!(image_format(Path::new("a.SVG")).unwrap(), ImageFormat::Svg);
        assert_eq!(image_format(Path::new("a.png")).unwrap(), ImageFormat::Png);
        assert!(image_format(Path::new("a.jpg")).is_err());
    }
}
