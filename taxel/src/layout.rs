//! Pad layouts for `taxel view`: which of a device's pads is which (a name) and where its tile
//! sits on a grid, read from TOML.
//!
//! ```toml
//! name = "two-finger gripper"
//! [[pad]]
//! index = 0          # the device's pad index, 0 to 7
//! name = "left finger"
//! column = 0         # grid cell, 0 to 7, counted from the left
//! row = 0            # grid cell, 0 to 7, counted from the top
//! ```
//!
//! [`Layout::load`] takes a built-in name ([`BUILT_IN`]: `gripper`, `glove`) or a file path;
//! [`Layout::parse`] validates once (indices 0 to 7 and unique, one pad per cell, names not
//! empty, unknown keys refused) and every error names the line. [`Layout::arrange`] fits a
//! layout to the device's pad count: pads the layout names that the device does not have are
//! kept and marked, pads the device has that the layout does not name are appended below it, so
//! no pad is ever silently hidden.

use std::collections::BTreeSet;
use std::fmt;
use std::path::Path;

use serde::Deserialize;
use toml::Spanned;

/// Pads a device can read (pad indices 0 to 7, one per TCA9548A channel).
pub const MAX_PADS: u8 = 8;

/// The largest grid column or row a layout may use: an 8 x 8 grid places any 8 pads.
pub const MAX_GRID_CELL: u16 = 7;

/// The built-in layouts: name and TOML text (the files in `taxel/layouts/`).
pub const BUILT_IN: [(&str, &str); 2] = [
    ("gripper", include_str!("../layouts/gripper.toml")),
    ("glove", include_str!("../layouts/glove.toml")),
];

/// Columns of the automatic grid (no `--layout`) and of the rows appended for pads a layout
/// does not name.
const AUTOMATIC_COLUMNS: u16 = 4;

/// One pad of a layout: the device's pad index, its name and its grid cell.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PadPlace {
    /// The device's pad index, 0 to 7.
    pub index: u8,
    /// What the pad is, e.g. "left finger".
    pub name: String,
    /// Grid column, 0 = leftmost.
    pub column: u16,
    /// Grid row, 0 = top.
    pub row: u16,
}

/// A validated layout: unique pad indices within 0 to 7, one pad per grid cell.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Layout {
    /// The layout's name, as the view's title shows it.
    pub name: String,
    /// The pads it names, in file order.
    pub pads: Vec<PadPlace>,
}

/// What is wrong with a layout (see [`LayoutError`] for where).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LayoutProblem {
    /// Not TOML, a key of the wrong type, a missing or unknown key.
    Syntax {
        /// Column of the error on its line, from 1.
        column: usize,
        /// The TOML reader's message.
        message: String,
    },
    /// A pad index outside 0 to 7.
    IndexOutOfRange {
        /// The pad's name.
        name: String,
        /// The index given.
        index: i64,
    },
    /// Two pads with one index.
    DuplicateIndex {
        /// The index given twice.
        index: u8,
        /// The first pad's name.
        first_name: String,
        /// The second pad's name.
        second_name: String,
    },
    /// A column or row outside 0 to [`MAX_GRID_CELL`].
    CellOutOfRange {
        /// The pad's name.
        name: String,
        /// The column given.
        column: i64,
        /// The row given.
        row: i64,
    },
    /// Two pads in one grid cell.
    SameCell {
        /// The cell's column.
        column: u16,
        /// The cell's row.
        row: u16,
        /// The first pad's name.
        first_name: String,
        /// The second pad's name.
        second_name: String,
    },
    /// A pad without a name.
    EmptyName {
        /// The pad's index.
        index: u8,
    },
    /// No `[[pad]]` at all.
    NoPads,
    /// `--layout` named neither a built-in layout nor a file.
    UnknownBuiltIn,
    /// The file could not be read.
    Read {
        /// The system's message.
        message: String,
    },
}

/// Why a layout was refused: where (the layout's origin, a file path or built-in name, and the
/// line when known) and what.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LayoutError {
    /// The file path or built-in name.
    pub origin: String,
    /// The line of the problem, from 1, when it has one.
    pub line: Option<usize>,
    /// What is wrong.
    pub problem: LayoutProblem,
}

impl fmt::Display for LayoutError {
    fn fmt(&self, formatter: &mut fmt::Formatter<'_>) -> fmt::Result {
        let origin = &self.origin;
        match &self.problem {
            LayoutProblem::UnknownBuiltIn => {
                return write!(
                    formatter,
                    "unknown layout \"{origin}\": the built-in layouts are {}; a layout file is \
                     given by its path (with a '/' or ending in .toml)",
                    built_in_names()
                );
            }
            LayoutProblem::Read { message } => {
                return write!(formatter, "cannot read layout file {origin}: {message}");
            }
            _ => {}
        }
        write!(formatter, "layout {origin}")?;
        if let Some(line) = self.line {
            write!(formatter, ", line {line}")?;
        }
        match &self.problem {
            LayoutProblem::Syntax { column, message } => {
                write!(formatter, ", column {column}: {}", message.trim_end())
            }
            LayoutProblem::IndexOutOfRange { name, index } => write!(
                formatter,
                ": pad \"{name}\" has index {index}; a device has pads 0 to {}",
                MAX_PADS - 1
            ),
            LayoutProblem::DuplicateIndex {
                index,
                first_name,
                second_name,
            } => write!(
                formatter,
                ": pad index {index} is given twice (\"{first_name}\" and \"{second_name}\")"
            ),
            LayoutProblem::CellOutOfRange { name, column, row } => write!(
                formatter,
                ": pad \"{name}\" is in column {column}, row {row}; columns and rows are 0 to \
                 {MAX_GRID_CELL}"
            ),
            LayoutProblem::SameCell {
                column,
                row,
                first_name,
                second_name,
            } => write!(
                formatter,
                ": \"{first_name}\" and \"{second_name}\" are both in column {column}, row {row}"
            ),
            LayoutProblem::EmptyName { index } => {
                write!(formatter, ": pad {index} has an empty name")
            }
            LayoutProblem::NoPads => write!(
                formatter,
                ": no pads; add [[pad]] tables with index, name, column and row"
            ),
            LayoutProblem::UnknownBuiltIn | LayoutProblem::Read { .. } => Ok(()),
        }
    }
}

impl std::error::Error for LayoutError {}

fn built_in_names() -> String {
    BUILT_IN
        .iter()
        .map(|(name, _)| *name)
        .collect::<Vec<_>>()
        .join(", ")
}

/// The file as written, with positions for the errors.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct LayoutFile {
    name: Option<String>,
    #[serde(default)]
    pad: Vec<PadPlaceFile>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PadPlaceFile {
    index: Spanned<i64>,
    name: String,
    column: Spanned<i64>,
    row: i64,
}

/// Line and column (both from 1) of a byte offset in `text`.
fn line_and_column(text: &str, offset: usize) -> (usize, usize) {
    let before = text.get(..offset).unwrap_or(text);
    let line = before.matches('\n').count() + 1;
    let column = before
        .rsplit('\n')
        .next()
        .map_or(0, |line_text| line_text.chars().count())
        + 1;
    (line, column)
}

impl Layout {
    /// Parses and validates a layout's TOML text; `origin` (a path or built-in name) is what
    /// errors name, and the name of a layout that has none.
    pub fn parse(text: &str, origin: &str) -> Result<Self, LayoutError> {
        let error = |line: Option<usize>, problem| LayoutError {
            origin: origin.to_owned(),
            line,
            problem,
        };
        let file: LayoutFile = toml::from_str(text).map_err(|parse_error| {
            let (line, column) = parse_error
                .span()
                .map(|span| line_and_column(text, span.start))
                .map_or((None, 0), |(line, column)| (Some(line), column));
            error(
                line,
                LayoutProblem::Syntax {
                    column,
                    message: parse_error.message().to_owned(),
                },
            )
        })?;
        if file.pad.is_empty() {
            return Err(error(None, LayoutProblem::NoPads));
        }
        let mut pads: Vec<PadPlace> = Vec::with_capacity(file.pad.len());
        for place in &file.pad {
            let line = Some(line_and_column(text, place.index.span().start).0);
            let name = place.name.trim().to_owned();
            let index = *place.index.get_ref();
            let Some(index) = u8::try_from(index).ok().filter(|index| *index < MAX_PADS) else {
                return Err(error(line, LayoutProblem::IndexOutOfRange { name, index }));
            };
            let (column, row) = (*place.column.get_ref(), place.row);
            let in_grid = |value: i64| {
                u16::try_from(value)
                    .ok()
                    .filter(|value| *value <= MAX_GRID_CELL)
            };
            let (Some(grid_column), Some(grid_row)) = (in_grid(column), in_grid(row)) else {
                let cell_line = Some(line_and_column(text, place.column.span().start).0);
                return Err(error(
                    cell_line,
                    LayoutProblem::CellOutOfRange { name, column, row },
                ));
            };
            if name.is_empty() {
                return Err(error(line, LayoutProblem::EmptyName { index }));
            }
            if let Some(first) = pads.iter().find(|pad| pad.index == index) {
                return Err(error(
                    line,
                    LayoutProblem::DuplicateIndex {
                        index,
                        first_name: first.name.clone(),
                        second_name: name,
                    },
                ));
            }
            if let Some(first) = pads
                .iter()
                .find(|pad| pad.column == grid_column && pad.row == grid_row)
            {
                return Err(error(
                    line,
                    LayoutProblem::SameCell {
                        column: grid_column,
                        row: grid_row,
                        first_name: first.name.clone(),
                        second_name: name,
                    },
                ));
            }
            pads.push(PadPlace {
                index,
                name,
                column: grid_column,
                row: grid_row,
            });
        }
        Ok(Self {
            name: file
                .name
                .map(|name| name.trim().to_owned())
                .filter(|name| !name.is_empty())
                .unwrap_or_else(|| origin.to_owned()),
            pads,
        })
    }

    /// A built-in layout by name (`gripper`, `glove`), `None` for another name.
    pub fn built_in(name: &str) -> Option<Result<Self, LayoutError>> {
        BUILT_IN
            .iter()
            .find(|(built_in_name, _)| *built_in_name == name)
            .map(|(built_in_name, text)| Self::parse(text, built_in_name))
    }

    /// What `--layout` names: a built-in layout, else a file. A name that is neither a
    /// built-in one nor an existing file, and does not look like a path (no '/', no `.toml`),
    /// is reported as an unknown built-in name.
    pub fn load(layout: &str) -> Result<Self, LayoutError> {
        if let Some(built_in) = Self::built_in(layout) {
            return built_in;
        }
        let path = Path::new(layout);
        let looks_like_path = layout.contains(std::path::MAIN_SEPARATOR)
            || layout.contains('/')
            || layout.ends_with(".toml");
        if !path.exists() && !looks_like_path {
            return Err(LayoutError {
                origin: layout.to_owned(),
                line: None,
                problem: LayoutProblem::UnknownBuiltIn,
            });
        }
        let text = std::fs::read_to_string(path).map_err(|read_error| LayoutError {
            origin: layout.to_owned(),
            line: None,
            problem: LayoutProblem::Read {
                message: read_error.to_string(),
            },
        })?;
        Self::parse(&text, layout)
    }

    /// The layout without `--layout`: pads "pad 0" to "pad N-1" in pad order, four to a row.
    pub fn automatic(pad_count: u8) -> Self {
        Self {
            name: "automatic".to_owned(),
            pads: (0..pad_count.clamp(1, MAX_PADS))
                .map(|index| PadPlace {
                    index,
                    name: format!("pad {index}"),
                    column: u16::from(index) % AUTOMATIC_COLUMNS,
                    row: u16::from(index) / AUTOMATIC_COLUMNS,
                })
                .collect(),
        }
    }

    /// The layout's pad named `index`, if it names it.
    pub fn pad(&self, index: u8) -> Option<&PadPlace> {
        self.pads.iter().find(|pad| pad.index == index)
    }

    /// The tiles to draw on a device with `pad_count` pads (`None`: not known yet): the
    /// layout's pads, those the device does not have marked, then the device's pads the layout
    /// does not name, in pad order, in rows appended below the layout's grid.
    pub fn arrange(&self, pad_count: Option<u8>) -> Arrangement {
        let mut tiles: Vec<PadTile> = self
            .pads
            .iter()
            .map(|pad| PadTile {
                place: pad.clone(),
                on_device: pad_count.map(|count| pad.index < count),
                in_layout: true,
            })
            .collect();
        let mut columns = self
            .pads
            .iter()
            .map(|pad| pad.column + 1)
            .max()
            .unwrap_or(1);
        let mut rows = self.pads.iter().map(|pad| pad.row + 1).max().unwrap_or(1);
        let named: BTreeSet<u8> = self.pads.iter().map(|pad| pad.index).collect();
        let unnamed: Vec<u8> = (0..pad_count.unwrap_or(0).min(MAX_PADS))
            .filter(|index| !named.contains(index))
            .collect();
        if !unnamed.is_empty() {
            let extra_columns = columns.max(AUTOMATIC_COLUMNS.min(unnamed.len() as u16));
            for (position, index) in unnamed.iter().enumerate() {
                let position = position as u16;
                tiles.push(PadTile {
                    place: PadPlace {
                        index: *index,
                        name: format!("pad {index}"),
                        column: position % extra_columns,
                        row: rows + position / extra_columns,
                    },
                    on_device: Some(true),
                    in_layout: false,
                });
            }
            rows += (unnamed.len() as u16).div_ceil(extra_columns);
            columns = extra_columns;
        }
        Arrangement {
            name: self.name.clone(),
            tiles,
            columns,
            rows,
        }
    }
}

/// One tile of the view: a pad, its place, and whether the device has it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PadTile {
    /// The pad's index, name and grid cell.
    pub place: PadPlace,
    /// Whether the device has this pad (`None` until its pad count is known).
    pub on_device: Option<bool>,
    /// Whether the layout names the pad (false: a pad of the device the layout left out,
    /// appended).
    pub in_layout: bool,
}

/// A layout fitted to a device: every tile to draw and the grid's size in cells.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Arrangement {
    /// The layout's name.
    pub name: String,
    /// The tiles, the layout's first, then the appended ones.
    pub tiles: Vec<PadTile>,
    /// Grid columns.
    pub columns: u16,
    /// Grid rows.
    pub rows: u16,
}

impl Arrangement {
    /// Indices of the layout's pads the device does not have.
    pub fn not_on_device(&self) -> Vec<u8> {
        self.tiles
            .iter()
            .filter(|tile| tile.on_device == Some(false))
            .map(|tile| tile.place.index)
            .collect()
    }

    /// Indices of the device's pads the layout does not name (appended).
    pub fn not_in_layout(&self) -> Vec<u8> {
        self.tiles
            .iter()
            .filter(|tile| !tile.in_layout)
            .map(|tile| tile.place.index)
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_and_column_count_from_one() {
        assert_eq!(line_and_column("ab\ncd", 0), (1, 1));
        assert_eq!(line_and_column("ab\ncd", 4), (2, 2));
        assert_eq!(line_and_column("ab", 99), (1, 3));
    }

    #[test]
    fn the_built_in_layouts_are_valid() {
        for (name, _) in BUILT_IN {
            assert!(matches!(Layout::built_in(name), Some(Ok(_))), "{name}");
        }
    }
}
