//! A small SVG writer for the speed-vs-error scatter plot (linear x, log10 y, labelled points).
//!
//! Written by hand rather than with plotters: the workspace enables plotters' `ab_glyph` text
//! renderer (for PNG output elsewhere), and with it plotters refuses to lay out any text, SVG
//! included, until a font file is registered. Here text is plain `<text>` elements that the
//! viewer renders, so no font is needed at all.

use std::fmt::Write;

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
    /// CSS colour.
    pub colour: &'static str,
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
    /// CSS colour.
    pub colour: &'static str,
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
}

const WIDTH: f64 = 820.0;
const HEIGHT: f64 = 560.0;
const LEFT: f64 = 80.0;
const RIGHT: f64 = 30.0;
const TOP: f64 = 50.0;
const BOTTOM: f64 = 130.0;
const FONT_PX: f64 = 12.0;

/// An axis-aligned rectangle in SVG coordinates.
#[derive(Debug, Clone, Copy)]
struct Box {
    left: f64,
    right: f64,
    top: f64,
    bottom: f64,
}

impl Box {
    fn overlaps(&self, other: &Box) -> bool {
        self.left < other.right
            && other.left < self.right
            && self.top < other.bottom
            && other.top < self.bottom
    }
}

fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// The SVG document.
pub fn render(plot: &Plot) -> String {
    let x_max_data = plot
        .points
        .iter()
        .map(|point| point.x)
        .chain(plot.guides.iter().filter_map(|guide| match guide {
            Guide::Vertical(x, _) => Some(*x),
            Guide::Horizontal(..) => None,
        }))
        .fold(1.0, f64::max);
    let x_step = 50.0;
    let x_max = (x_max_data / x_step).ceil() * x_step + x_step;
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
        (
            y_min.log10().floor(),
            // Headroom: a point just under a decade line would otherwise sit on the frame.
            (y_max.log10() + 0.2)
                .ceil()
                .max(y_min.log10().floor() + 1.0),
        )
    } else {
        (-6.0, 1.0)
    };
    let plot_width = WIDTH - LEFT - RIGHT;
    let plot_height = HEIGHT - TOP - BOTTOM;
    let x_of = |x: f64| LEFT + x / x_max * plot_width;
    let y_of = |y: f64| {
        let decade = if y > 0.0 { y.log10() } else { decade_low };
        let fraction =
            (decade.clamp(decade_low, decade_high) - decade_low) / (decade_high - decade_low);
        TOP + (1.0 - fraction) * plot_height
    };

    let mut svg = String::new();
    let _ = writeln!(
        svg,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{HEIGHT}" viewBox="0 0 {WIDTH} {HEIGHT}" font-family="DejaVu Sans, Arial, Helvetica, sans-serif" font-size="{FONT_PX}">"#
    );
    let _ = writeln!(svg, r#"<rect width="100%" height="100%" fill="white"/>"#);
    let _ = writeln!(
        svg,
        r#"<text x="{}" y="28" text-anchor="middle" font-size="16">{}</text>"#,
        WIDTH / 2.0,
        escape(&plot.title)
    );
    let mut decade = decade_low;
    while decade <= decade_high + 1e-9 {
        let y = y_of(10f64.powf(decade));
        let _ = writeln!(
            svg,
            r##"<line x1="{LEFT}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" stroke="#dddddd"/>"##,
            WIDTH - RIGHT
        );
        let _ = writeln!(
            svg,
            r#"<text x="{:.1}" y="{:.1}" text-anchor="end">1e{}</text>"#,
            LEFT - 6.0,
            y + 4.0,
            decade as i32
        );
        decade += 1.0;
    }
    let mut tick = 0.0;
    while tick <= x_max + 1e-9 {
        let x = x_of(tick);
        let _ = writeln!(
            svg,
            r##"<line x1="{x:.1}" y1="{TOP}" x2="{x:.1}" y2="{:.1}" stroke="#eeeeee"/>"##,
            TOP + plot_height
        );
        let _ = writeln!(
            svg,
            r#"<text x="{x:.1}" y="{:.1}" text-anchor="middle">{tick}</text>"#,
            TOP + plot_height + 16.0
        );
        tick += x_step;
    }
    let _ = writeln!(
        svg,
        r#"<rect x="{LEFT}" y="{TOP}" width="{plot_width:.1}" height="{plot_height:.1}" fill="none" stroke="black"/>"#
    );
    let text_width = |text: &str| 0.62 * FONT_PX * text.chars().count() as f64;
    // Labels of the points avoid these, and the guides and links below.
    let mut placed: Vec<Box> = Vec::new();
    for guide in &plot.guides {
        match guide {
            Guide::Horizontal(value, label) => {
                let y = y_of(*value);
                placed.push(Box {
                    left: WIDTH - RIGHT - 4.0 - text_width(label),
                    right: WIDTH - RIGHT - 4.0,
                    top: y - 4.0 - FONT_PX,
                    bottom: y - 2.0,
                });
                let _ = writeln!(
                    svg,
                    r##"<line x1="{LEFT}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" stroke="#888888" stroke-dasharray="6,4"/>"##,
                    WIDTH - RIGHT
                );
                let _ = writeln!(
                    svg,
                    r##"<text x="{:.1}" y="{:.1}" text-anchor="end" fill="#555555">{}</text>"##,
                    WIDTH - RIGHT - 4.0,
                    y - 4.0,
                    escape(label)
                );
            }
            Guide::Vertical(value, label) => {
                let x = x_of(*value);
                placed.push(Box {
                    left: x + 4.0,
                    right: x + 4.0 + text_width(label),
                    top: TOP + 14.0 - FONT_PX,
                    bottom: TOP + 16.0,
                });
                let _ = writeln!(
                    svg,
                    r##"<line x1="{x:.1}" y1="{TOP}" x2="{x:.1}" y2="{:.1}" stroke="#888888" stroke-dasharray="6,4"/>"##,
                    TOP + plot_height
                );
                let _ = writeln!(
                    svg,
                    r##"<text x="{:.1}" y="{:.1}" fill="#555555">{}</text>"##,
                    x + 4.0,
                    TOP + 14.0,
                    escape(label)
                );
            }
        }
    }
    let mut lines: Vec<Box> = plot
        .guides
        .iter()
        .map(|guide| match guide {
            Guide::Horizontal(value, _) => Box {
                left: LEFT,
                right: WIDTH - RIGHT,
                top: y_of(*value) - 1.0,
                bottom: y_of(*value) + 1.0,
            },
            Guide::Vertical(value, _) => Box {
                left: x_of(*value) - 1.0,
                right: x_of(*value) + 1.0,
                top: TOP,
                bottom: TOP + plot_height,
            },
        })
        .collect();
    for link in &plot.links {
        let (x1, y1, x2, y2) = (
            x_of(link.from.0),
            y_of(link.from.1),
            x_of(link.to.0),
            y_of(link.to.1),
        );
        lines.push(Box {
            left: x1.min(x2),
            right: x1.max(x2),
            top: y1.min(y2) - 2.0,
            bottom: y1.max(y2) + 2.0,
        });
        let _ = writeln!(
            svg,
            r#"<line x1="{:.1}" y1="{:.1}" x2="{:.1}" y2="{:.1}" stroke="{}" stroke-width="1.5" stroke-opacity="0.6"/>"#,
            x_of(link.from.0),
            y_of(link.from.1),
            x_of(link.to.0),
            y_of(link.to.1),
            link.colour
        );
    }
    let markers: Vec<(f64, f64)> = plot
        .points
        .iter()
        .map(|point| (x_of(point.x), y_of(point.y)))
        .collect();
    for (point, (x, y)) in plot.points.iter().zip(&markers) {
        let fill = if point.filled { point.colour } else { "white" };
        let _ = writeln!(
            svg,
            r#"<circle cx="{x:.1}" cy="{y:.1}" r="5" fill="{fill}" stroke="{}" stroke-width="2"/>"#,
            point.colour
        );
    }
    for (point, (x, y)) in plot.points.iter().zip(&markers) {
        let Some(label) = &point.label else {
            continue;
        };
        let width = text_width(label);
        let candidates = (0..8).flat_map(|ring| {
            let step = ring as f64 * (FONT_PX + 2.0);
            [
                (x + 9.0, y + 4.0 + step, false),
                (x - 9.0, y + 4.0 + step, true),
                (x + 9.0, y - 10.0 - step, false),
                (x - 9.0, y - 10.0 - step, true),
                (x + 9.0, y + 18.0 + step, false),
            ]
        });
        let mut chosen = None;
        for (text_x, baseline, anchored_end) in candidates {
            let left = if anchored_end { text_x - width } else { text_x };
            let candidate = Box {
                left,
                right: left + width,
                top: baseline - FONT_PX,
                bottom: baseline + 2.0,
            };
            let inside = candidate.left >= LEFT
                && candidate.right <= WIDTH - RIGHT
                && candidate.top >= TOP
                && candidate.bottom <= TOP + plot_height;
            let free = placed
                .iter()
                .chain(&lines)
                .all(|other| !other.overlaps(&candidate))
                && markers.iter().all(|(marker_x, marker_y)| {
                    !candidate.overlaps(&Box {
                        left: marker_x - 6.0,
                        right: marker_x + 6.0,
                        top: marker_y - 6.0,
                        bottom: marker_y + 6.0,
                    })
                });
            if inside && free {
                chosen = Some((text_x, baseline, anchored_end, candidate));
                break;
            }
        }
        let (text_x, baseline, anchored_end, area) = chosen.unwrap_or((
            x + 9.0,
            y + 4.0,
            false,
            Box {
                left: x + 9.0,
                right: x + 9.0 + width,
                top: y - 8.0,
                bottom: y + 6.0,
            },
        ));
        placed.push(area);
        let _ = writeln!(
            svg,
            r#"<text x="{text_x:.1}" y="{baseline:.1}" text-anchor="{}" fill="{}">{}</text>"#,
            if anchored_end { "end" } else { "start" },
            point.colour,
            escape(label)
        );
    }
    let _ = writeln!(
        svg,
        r#"<text x="{:.1}" y="{:.1}" text-anchor="middle">{}</text>"#,
        LEFT + plot_width / 2.0,
        TOP + plot_height + 36.0,
        escape(&plot.x_label)
    );
    let _ = writeln!(
        svg,
        r#"<text x="18" y="{:.1}" text-anchor="middle" transform="rotate(-90 18 {:.1})">{}</text>"#,
        TOP + plot_height / 2.0,
        TOP + plot_height / 2.0,
        escape(&plot.y_label)
    );
    for (index, note) in plot.notes.iter().enumerate() {
        let _ = writeln!(
            svg,
            r##"<text x="{LEFT}" y="{:.1}" fill="#333333">{}</text>"##,
            TOP + plot_height + 60.0 + 16.0 * index as f64,
            escape(note)
        );
    }
    svg.push_str("</svg>\n");
    svg
}

#[cfg(test)]
mod tests {
    use super::*;

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
                    colour: "#1f77b4",
                },
                Point {
                    label: Some("saturating".to_string()),
                    x: 121.0,
                    y: 0.0147,
                    filled: true,
                    colour: "#ff7f0e",
                },
                Point {
                    label: None,
                    x: 160.0,
                    y: 1e-9,
                    filled: false,
                    colour: "#1f77b4",
                },
            ],
            guides: vec![
                Guide::Horizontal(0.5, "0.5 kPa".to_string()),
                Guide::Vertical(30.0, "30".to_string()),
            ],
            links: vec![Link {
                from: (119.0, 0.0146),
                to: (160.0, 0.0146),
                colour: "#1f77b4",
            }],
        }
    }

    #[test]
    fn the_document_has_every_point_label_and_escaped_text() {
        let svg = render(&sample());
        assert!(svg.starts_with("<svg ") && svg.ends_with("</svg>\n"));
        assert_eq!(svg.matches("<circle").count(), 3);
        assert_eq!(svg.matches("stroke-opacity").count(), 1);
        assert!(svg.find("stroke-opacity") < svg.find("<circle"));
        assert!(svg.contains(">table</text>") && svg.contains(">saturating</text>"));
        assert!(svg.contains("speed &lt;vs&gt; error"));
        assert!(!svg.contains("NaN") && !svg.contains("=\"inf"));
    }

    #[test]
    fn close_labels_overlap_neither_each_other_nor_the_markers() {
        let svg = render(&sample());
        let attribute = |element: &str, name: &str| -> String {
            let start = element.find(&format!(" {name}=\"")).unwrap() + name.len() + 3;
            element[start..].split('"').next().unwrap().to_string()
        };
        let label_box = |label: &str| -> Box {
            let end = svg.find(&format!(">{label}</text>")).unwrap();
            let element = &svg[svg[..end].rfind("<text").unwrap()..end];
            let x: f64 = attribute(element, "x").parse().unwrap();
            let y: f64 = attribute(element, "y").parse().unwrap();
            let width = 0.62 * FONT_PX * label.len() as f64;
            let left = if attribute(element, "text-anchor") == "end" {
                x - width
            } else {
                x
            };
            Box {
                left,
                right: left + width,
                top: y - FONT_PX,
                bottom: y + 2.0,
            }
        };
        let (table, saturating) = (label_box("table"), label_box("saturating"));
        assert!(!table.overlaps(&saturating), "{table:?} {saturating:?}");
        for line in svg.split("<line").skip(1) {
            if !line.contains("stroke-opacity") {
                continue;
            }
            let coordinate = |name: &str| -> f64 { attribute(line, name).parse().unwrap() };
            let link = Box {
                left: coordinate("x1").min(coordinate("x2")),
                right: coordinate("x1").max(coordinate("x2")),
                top: coordinate("y1").min(coordinate("y2")) - 1.0,
                bottom: coordinate("y1").max(coordinate("y2")) + 1.0,
            };
            assert!(!link.overlaps(&table), "{link:?} {table:?}");
        }
        for circle in svg.split("<circle").skip(1) {
            let x: f64 = attribute(circle, "cx").parse().unwrap();
            let y: f64 = attribute(circle, "cy").parse().unwrap();
            let marker = Box {
                left: x - 5.0,
                right: x + 5.0,
                top: y - 5.0,
                bottom: y + 5.0,
            };
            assert!(!marker.overlaps(&table) && !marker.overlaps(&saturating));
        }
    }
}
