//! The speed-vs-error picture (docs/speed-vs-error.svg): labelled points on a linear x axis and
//! a log10 y axis, with dashed reference lines, thin links between points and a solid line
//! through a chosen run of points (the Pareto front), drawn with
//! plotters as the host tool draws its plots (and with its embedded font, which plotters needs
//! to lay out any text).

use anyhow::anyhow;
use plotters::coord::Shift;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

/// One point of the plot.
#[derive(Debug, Clone, PartialEq)]
pub struct Point {
    /// Label written next to the point (None: no label).
    pub label: Option<String>,
    /// x value.
    pub x: f64,
    /// y value (> 0; smaller values are drawn at the bottom edge).
    pub y: f64,
    /// Filled (true) or hollow marker.
    pub filled: bool,
    /// Colour of the marker and its label.
    pub colour: RGBColor,
}

/// A dashed reference line with its label.
#[derive(Debug, Clone, PartialEq)]
pub enum Guide {
    /// Horizontal line at a y value.
    Horizontal(f64, String),
    /// Vertical line at an x value.
    Vertical(f64, String),
}

/// A thin line between two points in data coordinates (e.g. one tier's two measures).
#[derive(Debug, Clone, PartialEq)]
pub struct Link {
    /// Start (x, y).
    pub from: (f64, f64),
    /// End (x, y).
    pub to: (f64, f64),
    /// Colour of the line.
    pub colour: RGBColor,
}

/// Everything the plot shows.
#[derive(Debug, Clone, PartialEq)]
pub struct Plot {
    /// Title at the top.
    pub title: String,
    /// x-axis label.
    pub x_label: String,
    /// y-axis label.
    pub y_label: String,
    /// Lines under the x-axis label (legend, definitions).
    pub notes: Vec<String>,
    /// The points.
    pub points: Vec<Point>,
    /// Reference lines.
    pub guides: Vec<Guide>,
    /// Lines between points, drawn under the markers.
    pub links: Vec<Link>,
    /// A solid dark line through these (x, y) in order (the Pareto front), drawn under the
    /// markers; fewer than two draw nothing.
    pub front: Vec<(f64, f64)>,
}

const WIDTH_PX: u32 = 820;
const HEIGHT_PX: u32 = 560;
/// plotters writes an SVG font size of size / 1.24, so this is about 12 px of text.
const FONT_PX: u32 = 15;
const TITLE_FONT_PX: u32 = 20;
const NOTE_LINE_PX: u32 = 16;
const MARKER_RADIUS_PX: i32 = 5;
/// Space between a marker's centre and its label, px.
const LABEL_GAP_PX: i32 = 9;
const X_TICK_STEP: f64 = 50.0;
const GRID: RGBColor = RGBColor(0xdd, 0xdd, 0xdd);
const GUIDE: RGBColor = RGBColor(0x88, 0x88, 0x88);
const GUIDE_LABEL: RGBColor = RGBColor(0x55, 0x55, 0x55);
const NOTE: RGBColor = RGBColor(0x33, 0x33, 0x33);
const FRONT: RGBColor = RGBColor(0x22, 0x22, 0x22);

/// An axis-aligned rectangle in pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
struct PixelBox {
    left: i32,
    right: i32,
    top: i32,
    bottom: i32,
}

impl PixelBox {
    fn around((x, y): (i32, i32), half_size: i32) -> Self {
        PixelBox {
            left: x - half_size,
            right: x + half_size,
            top: y - half_size,
            bottom: y + half_size,
        }
    }

    fn spanning((x1, y1): (i32, i32), (x2, y2): (i32, i32), margin: i32) -> Self {
        PixelBox {
            left: x1.min(x2) - margin,
            right: x1.max(x2) + margin,
            top: y1.min(y2) - margin,
            bottom: y1.max(y2) + margin,
        }
    }

    fn overlaps(&self, other: &PixelBox) -> bool {
        self.left < other.right
            && other.left < self.right
            && self.top < other.bottom
            && other.top < self.bottom
    }

    fn contains(&self, other: &PixelBox) -> bool {
        self.left <= other.left
            && other.right <= self.right
            && self.top <= other.top
            && other.bottom <= self.bottom
    }
}

/// The axis ranges: x from 0 in steps of [`X_TICK_STEP`], y over whole decades.
struct Axes {
    x_max: f64,
    decade_low: i32,
    decade_high: i32,
}

impl Axes {
    fn of(plot: &Plot) -> Self {
        let x_max_data = plot
            .points
            .iter()
            .map(|point| point.x)
            .chain(plot.guides.iter().filter_map(|guide| match guide {
                Guide::Vertical(x, _) => Some(*x),
                Guide::Horizontal(..) => None,
            }))
            .filter(|x| x.is_finite())
            .fold(1.0, f64::max);
        let y_values = plot
            .points
            .iter()
            .map(|point| point.y)
            .chain(plot.guides.iter().filter_map(|guide| match guide {
                Guide::Horizontal(y, _) => Some(*y),
                Guide::Vertical(..) => None,
            }))
            .filter(|y| *y > 0.0 && y.is_finite());
        let (y_min, y_max) = y_values.fold((f64::INFINITY, f64::NEG_INFINITY), |(low, high), y| {
            (low.min(y), high.max(y))
        });
        let (decade_low, decade_high) = if y_min.is_finite() {
            let low = y_min.log10().floor();
            // Headroom: a point just under a decade line would otherwise sit on the frame.
            (low, (y_max.log10() + 0.2).ceil().max(low + 1.0))
        } else {
            (-6.0, 1.0)
        };
        Axes {
            x_max: (x_max_data / X_TICK_STEP).ceil() * X_TICK_STEP + X_TICK_STEP,
            decade_low: decade_low as i32,
            decade_high: decade_high as i32,
        }
    }

    /// Ticks on the x axis: 0 and every [`X_TICK_STEP`] up to `x_max`, which plotters places
    /// exactly there since the step is a round number.
    fn x_tick_count(&self) -> usize {
        (self.x_max / X_TICK_STEP).round() as usize + 1
    }

    fn decades(&self) -> Vec<f64> {
        (self.decade_low..=self.decade_high)
            .map(|decade| 10f64.powi(decade))
            .collect()
    }

    fn y_low(&self) -> f64 {
        10f64.powi(self.decade_low)
    }

    fn y_high(&self) -> f64 {
        10f64.powi(self.decade_high)
    }

    /// `(x, y)` moved onto the plotted range: values off the axes (y <= 0 included) are drawn
    /// at the edge.
    fn clamped(&self, (x, y): (f64, f64)) -> (f64, f64) {
        let y = if y > 0.0 {
            y.clamp(self.y_low(), self.y_high())
        } else {
            self.y_low()
        };
        (x.clamp(0.0, self.x_max), y)
    }
}

/// `from` moved `distance_px` towards `to` (not past the midpoint).
fn towards(from: (i32, i32), to: (i32, i32), distance_px: i32) -> (i32, i32) {
    let (dx, dy) = (f64::from(to.0 - from.0), f64::from(to.1 - from.1));
    let length_px = dx.hypot(dy);
    // `min` also turns the NaN of a zero-length line into a finite fraction.
    let fraction = (f64::from(distance_px) / length_px).min(0.5);
    (
        from.0 + (dx * fraction).round() as i32,
        from.1 + (dy * fraction).round() as i32,
    )
}

fn text_style(size_px: u32, colour: RGBColor, h_pos: HPos) -> TextStyle<'static> {
    ("sans-serif", size_px)
        .into_font()
        .color(&colour)
        .pos(Pos::new(h_pos, VPos::Top))
}

/// Where a point's label goes: the first spot beside, above or below its marker that stays in
/// the frame and clear of the other labels, the markers, the guides and the links.
fn place_label(
    marker: (i32, i32),
    (width, height): (i32, i32),
    frame: &PixelBox,
    taken: &[PixelBox],
) -> (HPos, PixelBox) {
    let (x, y) = marker;
    let centred = y - height / 2;
    let line = height + 2;
    let candidates = (0..8).flat_map(|ring| {
        let step = ring * line;
        [
            (HPos::Left, centred + step),
            (HPos::Right, centred + step),
            (HPos::Left, centred - line - step),
            (HPos::Right, centred - line - step),
            (HPos::Left, centred + line + step),
        ]
    });
    let area = |h_pos: HPos, top: i32| {
        let left = match h_pos {
            HPos::Right => x - LABEL_GAP_PX - width,
            _ => x + LABEL_GAP_PX,
        };
        PixelBox {
            left,
            right: left + width,
            top,
            bottom: top + height,
        }
    };
    candidates
        .map(|(h_pos, top)| (h_pos, area(h_pos, top)))
        .find(|(_, candidate)| {
            frame.contains(candidate) && taken.iter().all(|other| !other.overlaps(candidate))
        })
        .unwrap_or((HPos::Left, area(HPos::Left, centred)))
}

/// Draws `text` into `area`, anchored at its left or right edge as `style` says.
fn draw_text<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    text: &str,
    style: TextStyle,
    area: PixelBox,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let x = if matches!(style.pos.h_pos, HPos::Right) {
        area.right
    } else {
        area.left
    };
    root.draw(&Text::new(text, (x, area.top), style))
}

fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    plot: &Plot,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    root.fill(&WHITE)?;
    let notes_height_px = NOTE_LINE_PX * plot.notes.len() as u32 + 12;
    let (chart_area, notes_area) = root.split_vertically(HEIGHT_PX - notes_height_px);
    let axes = Axes::of(plot);
    let mut chart = ChartBuilder::on(&chart_area)
        .caption(&plot.title, ("sans-serif", TITLE_FONT_PX))
        .margin(16)
        .x_label_area_size(44)
        .y_label_area_size(56)
        .build_cartesian_2d(
            0.0..axes.x_max,
            (axes.y_low()..axes.y_high())
                .log_scale()
                .with_key_points(axes.decades()),
        )?;
    chart
        .configure_mesh()
        .x_desc(plot.x_label.as_str())
        .y_desc(plot.y_label.as_str())
        .x_labels(axes.x_tick_count())
        .max_light_lines(0)
        .x_label_formatter(&|x| format!("{x}"))
        .y_label_formatter(&|y| format!("1e{}", y.log10().round() as i32))
        .label_style(("sans-serif", FONT_PX))
        .axis_desc_style(("sans-serif", FONT_PX))
        .bold_line_style(GRID)
        .draw()?;
    let (x_pixels, y_pixels) = chart.plotting_area().get_pixel_range();
    let frame = PixelBox {
        left: x_pixels.start,
        right: x_pixels.end,
        top: y_pixels.start,
        bottom: y_pixels.end,
    };
    // plotters draws the axes one pixel left of and below the plotting area: the frame joins
    // them and runs along the top and right grid lines.
    root.draw(&Rectangle::new(
        [(frame.left - 1, frame.top), (frame.right - 1, frame.bottom)],
        BLACK,
    ))?;
    let pixel = |point: (f64, f64)| chart.backend_coord(&axes.clamped(point));
    let text_size = |text: &str, style: &TextStyle| {
        root.estimate_text_size(text, style)
            .map(|(width, height)| (width as i32, height as i32))
    };

    // Labels of the points keep clear of everything in `taken`.
    let mut taken = Vec::new();
    for guide in &plot.guides {
        let (line, label) = match guide {
            Guide::Horizontal(y, label) => ([(0.0, *y), (axes.x_max, *y)], label),
            Guide::Vertical(x, label) => ([(*x, axes.y_low()), (*x, axes.y_high())], label),
        };
        let [start, end] = line.map(pixel);
        root.draw(&DashedPathElement::new(
            [start, end],
            6,
            4,
            GUIDE.stroke_width(1),
        ))?;
        taken.push(PixelBox::spanning(start, end, 1));
        let h_pos = match guide {
            Guide::Horizontal(..) => HPos::Right,
            Guide::Vertical(..) => HPos::Left,
        };
        let style = text_style(FONT_PX, GUIDE_LABEL, h_pos);
        let (width, height) = text_size(label, &style)?;
        let (left, top) = match guide {
            Guide::Horizontal(..) => (frame.right - 4 - width, start.1 - 3 - height),
            Guide::Vertical(..) => (start.0 + 4, frame.top + 3),
        };
        let area = PixelBox {
            left,
            right: left + width,
            top,
            bottom: top + height,
        };
        taken.push(area);
        draw_text(root, label, style, area)?;
    }
    for link in &plot.links {
        let (start, end) = (pixel(link.from), pixel(link.to));
        taken.push(PixelBox::spanning(start, end, 2));
        // Ending at the markers' rims keeps the hollow markers' insides empty.
        root.draw(&PathElement::new(
            [
                towards(start, end, MARKER_RADIUS_PX),
                towards(end, start, MARKER_RADIUS_PX),
            ],
            link.colour.mix(0.6).stroke_width(2),
        ))?;
    }
    let front: Vec<(i32, i32)> = plot.front.iter().map(|point| pixel(*point)).collect();
    for pair in front.windows(2) {
        let &[start, end] = pair else {
            continue;
        };
        taken.push(PixelBox::spanning(start, end, 2));
        root.draw(&PathElement::new(
            [
                towards(start, end, MARKER_RADIUS_PX),
                towards(end, start, MARKER_RADIUS_PX),
            ],
            FRONT.stroke_width(1),
        ))?;
    }
    let markers: Vec<(i32, i32)> = plot
        .points
        .iter()
        .map(|point| pixel((point.x, point.y)))
        .collect();
    for (point, marker) in plot.points.iter().zip(&markers) {
        taken.push(PixelBox::around(*marker, MARKER_RADIUS_PX + 1));
        let style = if point.filled {
            point.colour.filled()
        } else {
            // A white disc under the ring would be a second mark: the ring stays open instead.
            point.colour.stroke_width(2)
        };
        let radius = if point.filled {
            MARKER_RADIUS_PX + 1
        } else {
            MARKER_RADIUS_PX
        };
        root.draw(&Circle::new(*marker, radius, style))?;
    }
    for (point, marker) in plot.points.iter().zip(&markers) {
        let Some(label) = &point.label else {
            continue;
        };
        let size = text_size(label, &text_style(FONT_PX, point.colour, HPos::Left))?;
        let (h_pos, area) = place_label(*marker, size, &frame, &taken);
        taken.push(area);
        draw_text(root, label, text_style(FONT_PX, point.colour, h_pos), area)?;
    }
    for (index, note) in plot.notes.iter().enumerate() {
        let top = 4 + NOTE_LINE_PX as i32 * index as i32;
        let style = text_style(FONT_PX, NOTE, HPos::Left);
        notes_area.draw(&Text::new(note.as_str(), (frame.left, top), style))?;
    }
    Ok(())
}

/// The plot as an SVG document.
pub fn render_svg(plot: &Plot) -> anyhow::Result<String> {
    taxel_plot_style::register_embedded_font()?;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (WIDTH_PX, HEIGHT_PX)).into_drawing_area();
        draw(&root, plot)
            .and_then(|()| root.present())
            .map_err(|error| anyhow!("drawing the speed-vs-error plot: {error}"))?;
    }
    Ok(svg)
}

#[cfg(test)]
mod tests {
    use super::*;

    const BLUE: RGBColor = RGBColor(0x1f, 0x77, 0xb4);
    const ORANGE: RGBColor = RGBColor(0xff, 0x7f, 0x0e);

    fn sample() -> Plot {
        Plot {
            title: "speed <vs> error".to_string(),
            x_label: "instructions".to_string(),
            y_label: "kPa".to_string(),
            notes: vec!["filled: opt-level 3".to_string()],
            points: vec![
                Point {
                    label: Some("table".to_string()),
                    x: 119.0,
                    y: 0.0146,
                    filled: true,
                    colour: BLUE,
                },
                Point {
                    label: Some("saturating".to_string()),
                    x: 121.0,
                    y: 0.0147,
                    filled: true,
                    colour: ORANGE,
                },
                Point {
                    label: None,
                    x: 160.0,
                    y: 1e-9,
                    filled: false,
                    colour: BLUE,
                },
            ],
            guides: vec![
                Guide::Horizontal(0.5, "0.5 kPa".to_string()),
                Guide::Vertical(30.0, "30".to_string()),
            ],
            links: vec![Link {
                from: (119.0, 0.0146),
                to: (160.0, 0.0146),
                colour: BLUE,
            }],
            front: vec![(119.0, 0.0146), (160.0, 1e-9)],
        }
    }

    fn attribute(element: &str, name: &str) -> f64 {
        let start = element.find(&format!(" {name}=\"")).unwrap() + name.len() + 3;
        element[start..].split('"').next().unwrap().parse().unwrap()
    }

    #[test]
    fn the_document_has_the_title_every_label_and_a_mark_per_point() {
        let svg = render_svg(&sample()).unwrap();
        assert!(svg.starts_with("<svg ") && svg.trim_end().ends_with("</svg>"));
        assert_eq!(svg.matches("<circle").count(), sample().points.len());
        assert!(svg.contains("speed &lt;vs&gt; error"));
        for text in ["table", "saturating", "0.5 kPa", "instructions", "kPa"] {
            assert!(svg.contains(&format!(">\n{text}\n</text>")), "{text}");
        }
        assert!(svg.contains(">\nfilled: opt-level 3\n</text>"));
        for decade in -9..=0 {
            assert!(
                svg.contains(&format!(">\n1e{decade}\n</text>")),
                "1e{decade}"
            );
        }
        assert!(!svg.contains("NaN") && !svg.contains("inf"));
        // The front's line, once, in its own colour.
        assert_eq!(svg.matches("stroke=\"#222222\"").count(), 1);
    }

    #[test]
    fn markers_sit_inside_the_frame_and_labels_clear_of_them_and_each_other() {
        let svg = render_svg(&sample()).unwrap();
        let frame_element = svg
            .split("<rect")
            .skip(1)
            .find(|element| {
                let tag = element.split('>').next().unwrap();
                tag.contains("fill=\"none\"")
            })
            .unwrap();
        let (left, top) = (attribute(frame_element, "x"), attribute(frame_element, "y"));
        let (right, bottom) = (
            left + attribute(frame_element, "width"),
            top + attribute(frame_element, "height"),
        );
        let markers: Vec<(f64, f64)> = svg
            .split("<circle")
            .skip(1)
            .map(|element| (attribute(element, "cx"), attribute(element, "cy")))
            .collect();
        for &(x, y) in &markers {
            assert!(left < x && x < right && top <= y && y <= bottom, "{x} {y}");
        }
        // The point below the axis range is drawn on the bottom edge.
        assert!(
            (markers[2].1 - bottom).abs() <= 1.0,
            "{:?} {bottom}",
            markers[2]
        );
        let label_box = |label: &str| -> (f64, f64, f64, f64) {
            let end = svg.find(&format!(">\n{label}\n</text>")).unwrap();
            let element = &svg[svg[..end].rfind("<text").unwrap()..end];
            let (x, y) = (attribute(element, "x"), attribute(element, "y"));
            let width = 0.62 * 12.0 * label.len() as f64;
            let left = if element.contains("text-anchor=\"end\"") {
                x - width
            } else {
                x
            };
            (left, left + width, y, y + 14.0)
        };
        let overlap = |a: (f64, f64, f64, f64), b: (f64, f64, f64, f64)| {
            a.0 < b.1 && b.0 < a.1 && a.2 < b.3 && b.2 < a.3
        };
        let (table, saturating) = (label_box("table"), label_box("saturating"));
        assert!(!overlap(table, saturating), "{table:?} {saturating:?}");
        for (x, y) in markers {
            let marker = (x - 5.0, x + 5.0, y - 5.0, y + 5.0);
            assert!(!overlap(marker, table) && !overlap(marker, saturating));
        }
    }
}
