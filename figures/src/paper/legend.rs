//! Legends drawn below a chart: a strip of entries, each a symbol and its label.

use plotters::prelude::*;

use super::Area;

/// One entry of a legend strip.
pub(super) struct LegendEntry {
    pub(super) label: String,
    color: RGBColor,
    kind: LegendKind,
}

#[derive(Clone, Copy, PartialEq)]
enum LegendKind {
    Patch,
    Line,
    Dashed,
    Point,
}

impl LegendEntry {
    pub(super) fn patch(label: &str, color: RGBColor) -> Self {
        Self::new(label, color, LegendKind::Patch)
    }
    pub(super) fn line(label: &str, color: RGBColor) -> Self {
        Self::new(label, color, LegendKind::Line)
    }
    pub(super) fn dashed(label: &str, color: RGBColor) -> Self {
        Self::new(label, color, LegendKind::Dashed)
    }
    pub(super) fn point(label: &str, color: RGBColor) -> Self {
        Self::new(label, color, LegendKind::Point)
    }
    fn new(label: &str, color: RGBColor, kind: LegendKind) -> Self {
        Self {
            label: label.to_string(),
            color,
            kind,
        }
    }
}

/// Draws `entries` left to right in rows inside `area`.
pub(super) fn draw_legend(area: &Area, entries: &[LegendEntry]) -> anyhow::Result<()> {
    let (width, _) = area.dim_in_pixel();
    let style: TextStyle = ("sans-serif", 19).into_font().into();
    let (mut x, mut y) = (80i32, 4i32);
    let text_width = |t: &str| {
        area.estimate_text_size(t, &style)
            .map_or(10 * t.len() as u32, |s| s.0) as i32
    };
    // an entry longer than a row is split at its last space that fits, and the rest follows as
    // an entry of its own without a symbol
    let mut split: Vec<(Option<&LegendEntry>, String)> = Vec::new();
    for e in entries {
        let mut rest = e.label.clone();
        let mut first = true;
        while 80 + 52 + text_width(&rest) > width as i32 {
            let cut = rest
                .char_indices()
                .filter(|&(i, c)| c == ' ' && 80 + 52 + text_width(&rest[..i]) <= width as i32)
                .map(|(i, _)| i)
                .next_back();
            let Some(cut) = cut else { break };
            split.push((first.then_some(e), rest[..cut].to_string()));
            rest = rest[cut + 1..].to_string();
            first = false;
        }
        split.push((first.then_some(e), rest));
    }
    for (entry, label) in &split {
        let text_w = text_width(label);
        let w = 30 + text_w + 22;
        if x + w > width as i32 && x > 80 {
            x = 80;
            y += 28;
        }
        let Some(e) = entry else {
            area.draw_text(label, &style, (x + 30, y + 1))?;
            x += w;
            continue;
        };
        let cy = y + 11;
        match e.kind {
            LegendKind::Patch => area.draw(&Rectangle::new(
                [(x, cy - 7), (x + 22, cy + 7)],
                ShapeStyle::from(&e.color).filled(),
            ))?,
            LegendKind::Line => {
                if e.color == WHITE {
                    // a white line shows on the dark cells it separates
                    area.draw(&Rectangle::new(
                        [(x, cy - 7), (x + 22, cy + 7)],
                        RGBColor(68, 1, 84).filled(),
                    ))?;
                }
                area.draw(&PathElement::new(
                    vec![(x, cy), (x + 22, cy)],
                    e.color.stroke_width(3),
                ))?
            }
            LegendKind::Dashed => {
                for s in [0, 9, 18] {
                    area.draw(&PathElement::new(
                        vec![(x + s, cy), (x + s + 5, cy)],
                        e.color.stroke_width(2),
                    ))?;
                }
            }
            LegendKind::Point => {
                area.draw(&Circle::new((x + 11, cy), 7, WHITE.filled()))?;
                area.draw(&Circle::new((x + 11, cy), 7, e.color.stroke_width(3)))?;
            }
        }
        if e.kind == LegendKind::Patch {
            area.draw(&Rectangle::new(
                [(x, cy - 7), (x + 22, cy + 7)],
                RGBColor(120, 120, 120).stroke_width(1),
            ))?;
        }
        area.draw_text(label, &style, (x + 30, y + 1))?;
        x += w;
    }
    Ok(())
}
