//! Top views of a plan as SVG: obstacles, their grown outlines, the path, numbered footprints.

use std::fmt::Write;

use crate::archie::steps::FOOT;
use crate::geom::{Circle, V2};
use crate::plan::{Foot, Plan};

/// Draws `plan` among `obstacles` (grown by `inflation`) from `start` to `goal`, titled.
pub fn render(
    title: &str,
    obstacles: &[Circle],
    inflation: f64,
    start: V2,
    goal: V2,
    plan: &Plan,
    foot_offset: f64,
) -> String {
    // The drawing's extent, with a margin, in metres; y up.
    let mut lo = V2 {
        x: start.x.min(goal.x),
        y: start.y.min(goal.y),
    };
    let mut hi = V2 {
        x: start.x.max(goal.x),
        y: start.y.max(goal.y),
    };
    for c in obstacles {
        let r = c.r + inflation;
        lo = V2 {
            x: lo.x.min(c.c.x - r),
            y: lo.y.min(c.c.y - r),
        };
        hi = V2 {
            x: hi.x.max(c.c.x + r),
            y: hi.y.max(c.c.y + r),
        };
    }
    for p in &plan.path {
        lo = V2 {
            x: lo.x.min(p.x),
            y: lo.y.min(p.y),
        };
        hi = V2 {
            x: hi.x.max(p.x),
            y: hi.y.max(p.y),
        };
    }
    let m = 0.5;
    let (w, h) = (hi.x - lo.x + 2.0 * m, hi.y - lo.y + 2.0 * m);
    let scale = 120.0; // px per metre
    let px = |p: V2| ((p.x - lo.x + m) * scale, (hi.y - p.y + m) * scale);
    let mut s = header(w * scale, h * scale + 40.0);
    for c in obstacles {
        let (x, y) = px(c.c);
        let _ = writeln!(
            s,
            r##"<circle cx="{x:.1}" cy="{y:.1}" r="{:.1}" fill="none" stroke="#999999" stroke-dasharray="6 4"/>"##,
            (c.r + inflation) * scale
        );
        let _ = writeln!(
            s,
            r##"<circle cx="{x:.1}" cy="{y:.1}" r="{:.1}" fill="#b0b0b0"/>"##,
            c.r * scale
        );
    }
    let caption = format!(
        "{}: {}, cost {:.3} m, {} steps, {} expansions",
        escape(title),
        plan.status.name(),
        plan.cost,
        plan.steps.len(),
        plan.stats.expansions
    );
    overlay(
        &mut s,
        plan,
        start,
        goal,
        foot_offset,
        scale,
        &px,
        h * scale + 25.0,
        &caption,
    );
    s.push_str("</svg>\n");
    s
}

/// The document's opening and a white background, `w` × `h` pixels.
fn header(w: f64, h: f64) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w:.0}" height="{h:.0}" viewBox="0 0 {w:.0} {h:.0}" font-family="sans-serif">"#
    );
    let _ = writeln!(s, r##"<rect width="100%" height="100%" fill="#ffffff"/>"##);
    s
}

/// The path, the footprints, start and goal, and the caption.
#[allow(clippy::too_many_arguments)]
fn overlay(
    s: &mut String,
    plan: &Plan,
    start: V2,
    goal: V2,
    foot_offset: f64,
    scale: f64,
    px: &dyn Fn(V2) -> (f64, f64),
    caption_y: f64,
    caption: &str,
) {
    if plan.path.len() > 1 {
        let pts: Vec<String> = plan
            .path
            .iter()
            .map(|&p| {
                let (x, y) = px(p);
                format!("{x:.1},{y:.1}")
            })
            .collect();
        let _ = writeln!(
            s,
            r##"<polyline points="{}" fill="none" stroke="#2060c0" stroke-width="2"/>"##,
            pts.join(" ")
        );
    }
    for (k, f) in plan.steps.iter().enumerate() {
        footprint(s, k, f, foot_offset, scale, &px);
    }
    for (p, colour, label) in [(start, "#20a040", "start"), (goal, "#d03030", "goal")] {
        let (x, y) = px(p);
        let _ = writeln!(
            s,
            r#"<circle cx="{x:.1}" cy="{y:.1}" r="5" fill="{colour}"/><text x="{:.1}" y="{:.1}" font-size="12" fill="{colour}">{label}</text>"#,
            x + 7.0,
            y - 7.0
        );
    }
    let _ = writeln!(
        s,
        r##"<text x="8" y="{caption_y:.0}" font-size="14" fill="#000000">{caption}</text>"##
    );
}

/// Draws `plan` on an elevation grid (grey by height up to 0.3 m, black above, pink where
/// unknown), from `start` to `goal`, titled; the cost is in `unit`.
pub fn render_grid(
    title: &str,
    grid: &crate::grid::Grid,
    start: V2,
    goal: V2,
    plan: &Plan,
    unit: &str,
) -> String {
    let scale = 100.0;
    let (w, h) = (grid.nx as f64 * grid.res, grid.ny as f64 * grid.res);
    let lo = grid.origin;
    let px = |p: V2| ((p.x - lo.x) * scale, (lo.y + h - p.y) * scale);
    let mut s = header(w * scale, h * scale + 40.0);
    let cell = grid.res * scale;
    for j in 0..grid.ny {
        for i in 0..grid.nx {
            let z = grid.h[j * grid.nx + i];
            let fill = if z.is_nan() {
                "#f4c0d0".to_string()
            } else if z.abs() < 1e-9 {
                continue;
            } else {
                let g = (230.0 * (1.0 - (z / 0.3).clamp(0.0, 1.0))) as u8;
                format!("#{g:02x}{g:02x}{g:02x}")
            };
            let (x, y) = px(grid.centre(i, j));
            let _ = writeln!(
                s,
                r#"<rect x="{:.1}" y="{:.1}" width="{cell:.1}" height="{cell:.1}" fill="{fill}"/>"#,
                x - cell / 2.0,
                y - cell / 2.0
            );
        }
    }
    let caption = format!(
        "{}: {}, cost {:.1} {unit}, {} steps, {} expansions",
        escape(title),
        plan.status.name(),
        plan.cost,
        plan.steps.len().saturating_sub(2),
        plan.stats.expansions
    );
    overlay(
        &mut s,
        plan,
        start,
        goal,
        0.0,
        scale,
        &px,
        h * scale + 25.0,
        &caption,
    );
    s.push_str("</svg>\n");
    s
}

fn footprint(
    s: &mut String,
    k: usize,
    f: &Foot,
    offset: f64,
    scale: f64,
    px: &dyn Fn(V2) -> (f64, f64),
) {
    let dir = V2::polar(f.yaw);
    let side = V2 {
        x: -dir.y,
        y: dir.x,
    };
    let c = f.p + dir * offset;
    let corners: Vec<String> = [(1.0, 1.0), (1.0, -1.0), (-1.0, -1.0), (-1.0, 1.0)]
        .iter()
        .map(|&(a, b)| {
            let (x, y) = px(c + dir * (a * FOOT.0 / 2.0) + side * (b * FOOT.1 / 2.0));
            format!("{x:.1},{y:.1}")
        })
        .collect();
    let colour = if f.left { "#3070e0" } else { "#e05030" };
    let (tx, ty) = px(c);
    let _ = writeln!(
        s,
        r#"<polygon points="{}" fill="{colour}" fill-opacity="0.35" stroke="{colour}"/><text x="{tx:.1}" y="{:.1}" font-size="9" text-anchor="middle">{k}</text>"#,
        corners.join(" "),
        ty + 3.0
    );
    let _ = scale;
}

fn escape(t: &str) -> String {
    t.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}
