//! The page: a top view, the elevation map, the joints' tracking and the latencies.

use std::fmt::Write as _;

use stride_lcmtypes::stride::ObstacleT;

use crate::data::{Data, Foot};
use crate::png::{base64, gray_png};

/// The planner's sole box (m): the footprints drawn.
const SOLE: [f64; 2] = [0.225, 0.10];

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// At most `n` points of `v`, evenly picked, the last kept.
fn thin<T: Copy>(v: &[T], n: usize) -> Vec<T> {
    if v.len() <= n || n < 2 {
        return v.to_vec();
    }
    let step = v.len() as f64 / (n - 1) as f64;
    let mut out: Vec<T> = (0..n - 1).map(|i| v[(i as f64 * step) as usize]).collect();
    out.push(v[v.len() - 1]);
    out
}

/// A plotted line (pixel coordinates, x increasing) as few points as draw it alike: in each
/// pixel column its lowest and highest point in their order (every peak kept, unlike picking
/// every n-th point), the line's first and last, points that round to the one before dropped.
fn columns(xy: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let mut out: Vec<(f64, f64)> = Vec::new();
    let mut push = |p: (f64, f64)| {
        let round = |v: f64| (v * 10.0).round();
        if out
            .last()
            .is_none_or(|q| round(q.0) != round(p.0) || round(q.1) != round(p.1))
        {
            out.push(p);
        }
    };
    let mut i = 0;
    while i < xy.len() {
        let col = xy[i].0.floor();
        let mut j = i;
        let (mut lo, mut hi) = (i, i);
        while j < xy.len() && xy[j].0.floor() == col {
            if xy[j].1 < xy[lo].1 {
                lo = j;
            }
            if xy[j].1 > xy[hi].1 {
                hi = j;
            }
            j += 1;
        }
        let (a, b) = (lo.min(hi), lo.max(hi));
        if i == 0 {
            push(xy[0]);
        }
        push(xy[a]);
        push(xy[b]);
        i = j;
    }
    if let Some(&last) = xy.last() {
        push(last);
    }
    out
}

/// The q-quantile of sorted values.
fn quantile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    sorted[((sorted.len() - 1) as f64 * q).round() as usize]
}

/// A world-to-picture mapping for the top view.
struct View {
    min: [f64; 2],
    max: [f64; 2],
    s: f64,
    pad: f64,
}

impl View {
    fn x(&self, x: f64) -> f64 {
        self.pad + (x - self.min[0]) * self.s
    }
    fn y(&self, y: f64) -> f64 {
        self.pad + (self.max[1] - y) * self.s
    }
    fn size(&self) -> (f64, f64) {
        (
            2.0 * self.pad + (self.max[0] - self.min[0]) * self.s,
            2.0 * self.pad + (self.max[1] - self.min[1]) * self.s,
        )
    }
}

fn footprint(v: &View, f: &Foot, style: &str) -> String {
    let (_, x, y, yaw) = *f;
    let (w, h) = (SOLE[0] * v.s, SOLE[1] * v.s);
    format!(
        "<rect x=\"{:.1}\" y=\"{:.1}\" width=\"{w:.1}\" height=\"{h:.1}\" transform=\"rotate({:.1} {:.1} {:.1})\" {style}/>",
        v.x(x) - w / 2.0,
        v.y(y) - h / 2.0,
        -yaw.to_degrees(),
        v.x(x),
        v.y(y)
    )
}

fn obstacle(v: &View, o: &ObstacleT) -> String {
    let style = "fill=\"#b55\" fill-opacity=\"0.45\" stroke=\"#822\"";
    if o.vertices.len() >= 3 {
        let pts: Vec<String> = o
            .vertices
            .iter()
            .map(|p| format!("{:.1},{:.1}", v.x(p[0]), v.y(p[1])))
            .collect();
        let grow = if o.radius > 0.0 {
            format!(
                " stroke-width=\"{:.1}\" stroke-linejoin=\"round\"",
                2.0 * o.radius * v.s
            )
        } else {
            String::new()
        };
        format!("<polygon points=\"{}\" {style}{grow}/>", pts.join(" "))
    } else {
        format!(
            "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"{:.1}\" {style}/>",
            v.x(o.center[0]),
            v.y(o.center[1]),
            o.radius * v.s
        )
    }
}

/// The top view, or None with nothing to draw.
fn top_view(d: &Data) -> Option<String> {
    let mut pts: Vec<[f64; 2]> = Vec::new();
    if let Some(m) = &d.map {
        pts.push([m.origin_x, m.origin_y]);
        pts.push([
            m.origin_x + m.nx as f64 * m.resolution,
            m.origin_y + m.ny as f64 * m.resolution,
        ]);
    }
    for o in &d.obstacles {
        pts.push([o.center[0] - o.radius, o.center[1] - o.radius]);
        pts.push([o.center[0] + o.radius, o.center[1] + o.radius]);
        pts.extend(o.vertices.iter().map(|p| [p[0], p[1]]));
    }
    pts.extend(&d.trace);
    pts.extend(d.plans.iter().flatten().map(|f| [f.1, f.2]));
    pts.extend(d.touchdowns.iter().map(|f| [f.1, f.2]));
    pts.extend(d.goal);
    let pts: Vec<[f64; 2]> = pts
        .into_iter()
        .filter(|p| p[0].is_finite() && p[1].is_finite())
        .collect();
    if pts.is_empty() {
        return None;
    }
    let mut min = [f64::INFINITY; 2];
    let mut max = [f64::NEG_INFINITY; 2];
    for p in &pts {
        for k in 0..2 {
            min[k] = min[k].min(p[k] - 0.2);
            max[k] = max[k].max(p[k] + 0.2);
        }
    }
    let span = (max[0] - min[0]).max(max[1] - min[1]).max(0.5);
    let v = View {
        min,
        max,
        s: 900.0 / span,
        pad: 20.0,
    };
    let (w, h) = v.size();
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w:.0}\" height=\"{h:.0}\" viewBox=\"0 0 {w:.0} {h:.0}\" style=\"background:#fff\">"
    );
    if let Some(m) = &d.map {
        let _ = write!(
            s,
            "<rect x=\"{:.1}\" y=\"{:.1}\" width=\"{:.1}\" height=\"{:.1}\" fill=\"#f4f4f0\" stroke=\"#bbb\"/>",
            v.x(m.origin_x),
            v.y(m.origin_y + m.ny as f64 * m.resolution),
            m.nx as f64 * m.resolution * v.s,
            m.ny as f64 * m.resolution * v.s
        );
    }
    for o in &d.obstacles {
        s += &obstacle(&v, o);
    }
    for plan in &d.plans {
        for f in plan {
            s += &footprint(
                &v,
                f,
                "fill=\"none\" stroke=\"#39c\" stroke-opacity=\"0.25\"",
            );
        }
    }
    for f in &d.touchdowns {
        let colour = if f.0 == 0 { "#2a7" } else { "#e80" };
        s += &footprint(
            &v,
            f,
            &format!("fill=\"{colour}\" fill-opacity=\"0.55\" stroke=\"{colour}\""),
        );
    }
    if d.trace.len() >= 2 {
        let p: Vec<String> = thin(&d.trace, 3000)
            .iter()
            .map(|p| format!("{:.1},{:.1}", v.x(p[0]), v.y(p[1])))
            .collect();
        let _ = write!(
            s,
            "<polyline points=\"{}\" fill=\"none\" stroke=\"#c00\" stroke-width=\"1.5\"/>",
            p.join(" ")
        );
    }
    if let Some(g) = d.goal {
        let _ = write!(
            s,
            "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"8\" fill=\"none\" stroke=\"#000\" stroke-width=\"2\"/><text x=\"{:.1}\" y=\"{:.1}\" font-size=\"13\">goal</text>",
            v.x(g[0]),
            v.y(g[1]),
            v.x(g[0]) + 10.0,
            v.y(g[1]) - 10.0
        );
    }
    // A metre, for scale.
    let _ = write!(
        s,
        "<line x1=\"20\" y1=\"{y:.1}\" x2=\"{x2:.1}\" y2=\"{y:.1}\" stroke=\"#000\" stroke-width=\"3\"/><text x=\"20\" y=\"{ty:.1}\" font-size=\"12\">1 m</text></svg>",
        y = h - 8.0,
        x2 = 20.0 + v.s,
        ty = h - 12.0
    );
    Some(s)
}

/// The elevation map as a PNG data URI (black lowest, white highest, unknown black), or None.
fn map_png(d: &Data) -> Option<(String, String)> {
    let m = d.map.as_ref()?;
    let (nx, ny) = (m.nx.max(0) as usize, m.ny.max(0) as usize);
    if nx == 0 || ny == 0 || m.elevation.len() < nx * ny {
        return None;
    }
    let finite = m.elevation.iter().filter(|v| v.is_finite());
    let lo = finite.clone().fold(f32::INFINITY, |a, &b| a.min(b));
    let hi = finite.fold(f32::NEG_INFINITY, |a, &b| a.max(b));
    let span = if hi > lo { hi - lo } else { 1.0 };
    // Rows from the top: y decreasing.
    let mut px = Vec::with_capacity(nx * ny);
    for iy in (0..ny).rev() {
        for ix in 0..nx {
            let e = m.elevation[iy * nx + ix];
            px.push(if e.is_finite() {
                (32.0 + 223.0 * (e - lo) / span) as u8
            } else {
                0
            });
        }
    }
    let png = gray_png(nx as u32, ny as u32, &px);
    Some((
        format!("data:image/png;base64,{}", base64(&png)),
        format!(
            "{nx} × {ny} cells of {:.3} m from ({:.2}, {:.2}); heights {lo:.3} to {hi:.3} m",
            m.resolution, m.origin_x, m.origin_y
        ),
    ))
}

/// One joint's tracking: positions commanded and measured, and the error; with its max and
/// RMS error.
fn joint_plot(commanded: &[(f64, f64)], measured: &[(f64, f64)]) -> (String, f64, f64) {
    let at = |t: f64| -> Option<f64> {
        let i = commanded.partition_point(|c| c.0 <= t);
        if i == 0 || i >= commanded.len() {
            return None;
        }
        let (a, b) = (commanded[i - 1], commanded[i]);
        let s = if b.0 > a.0 {
            (t - a.0) / (b.0 - a.0)
        } else {
            0.0
        };
        Some(a.1 + s * (b.1 - a.1))
    };
    let err: Vec<(f64, f64)> = measured
        .iter()
        .filter_map(|&(t, p)| at(t).map(|c| (t, p - c)))
        .collect();
    let max = err.iter().fold(0.0f64, |m, e| m.max(e.1.abs()));
    let rms = if err.is_empty() {
        f64::NAN
    } else {
        (err.iter().map(|e| e.1 * e.1).sum::<f64>() / err.len() as f64).sqrt()
    };
    let all = commanded.iter().chain(measured);
    let (t0, t1) = all
        .clone()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
            (a.min(p.0), b.max(p.0))
        });
    let (p0, p1) = all.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
        (a.min(p.1), b.max(p.1))
    });
    let (w, h, he) = (520.0, 110.0, 60.0);
    let tx = |t: f64| 40.0 + (t - t0) / (t1 - t0).max(1e-9) * (w - 50.0);
    let py = |p: f64| 8.0 + (p1 - p) / (p1 - p0).max(1e-9) * (h - 16.0);
    let emax = max.max(1e-6);
    let ey = |e: f64| h + 8.0 + (emax - e) / (2.0 * emax) * (he - 16.0);
    let line = |pts: &[(f64, f64)], f: &dyn Fn(f64) -> f64, colour: &str| {
        let xy: Vec<(f64, f64)> = pts.iter().map(|&(t, v)| (tx(t), f(v))).collect();
        let p: Vec<String> = columns(&xy)
            .iter()
            .map(|&(x, y)| format!("{x:.1},{y:.1}"))
            .collect();
        format!(
            "<polyline points=\"{}\" fill=\"none\" stroke=\"{colour}\" stroke-width=\"1\"/>",
            p.join(" ")
        )
    };
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{}\" style=\"background:#fff\">",
        h + he
    );
    s += &line(commanded, &py, "#39c");
    s += &line(measured, &py, "#e80");
    let _ = write!(
        s,
        "<line x1=\"40\" y1=\"{z:.1}\" x2=\"{w}\" y2=\"{z:.1}\" stroke=\"#ccc\"/>",
        z = ey(0.0)
    );
    s += &line(&err, &ey, "#c00");
    let _ = write!(
        s,
        "<text x=\"2\" y=\"14\" font-size=\"10\">{p1:.2}</text><text x=\"2\" y=\"{:.0}\" font-size=\"10\">{p0:.2}</text><text x=\"2\" y=\"{:.0}\" font-size=\"10\">±{emax:.3}</text><text x=\"{:.0}\" y=\"{:.0}\" font-size=\"10\">{:.0} s</text></svg>",
        h - 4.0,
        h + 18.0,
        w - 40.0,
        h + he - 4.0,
        t1
    );
    (s, max, rms)
}

/// A small histogram of `v` (ms): bars over [0, p99.9] and the quantiles.
fn histogram(v: &[f64], w: f64, h: f64) -> String {
    let mut sorted: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    sorted.sort_by(f64::total_cmp);
    if sorted.is_empty() {
        return String::new();
    }
    let lo = sorted[0].min(0.0);
    let hi = quantile(&sorted, 0.999).max(lo + 1e-3);
    let bins = 40;
    let mut counts = vec![0u32; bins];
    for x in &sorted {
        let k = (((x - lo) / (hi - lo)) * bins as f64)
            .floor()
            .clamp(0.0, bins as f64 - 1.0);
        counts[k as usize] += 1;
    }
    let top = *counts.iter().max().unwrap_or(&1) as f64;
    let bw = w / bins as f64;
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{}\" style=\"background:#fff\">",
        h + 14.0
    );
    for (k, c) in counts.iter().enumerate() {
        let bh = *c as f64 / top * h;
        let _ = write!(
            s,
            "<rect x=\"{:.1}\" y=\"{:.1}\" width=\"{:.1}\" height=\"{bh:.1}\" fill=\"#39c\"/>",
            k as f64 * bw,
            h - bh,
            (bw - 1.0).max(0.5)
        );
    }
    let _ = write!(
        s,
        "<text x=\"0\" y=\"{:.0}\" font-size=\"10\">{lo:.1}</text><text x=\"{:.0}\" y=\"{:.0}\" font-size=\"10\" text-anchor=\"end\">{hi:.1} ms</text></svg>",
        h + 12.0,
        w,
        h + 12.0
    );
    s
}

/// The whole page.
pub fn html(d: &Data, source: &str) -> String {
    let mut s = String::new();
    let _ = write!(
        s,
        "<!DOCTYPE html><html><head><meta charset=\"utf-8\"><title>stride report: {src}</title><style>body{{font-family:sans-serif;margin:1.5em;max-width:1100px}}table{{border-collapse:collapse}}td,th{{padding:2px 8px;border-bottom:1px solid #ddd;text-align:left;font-size:13px}}.warn{{background:#fff3cd;padding:.5em 1em}}.plots{{display:flex;flex-wrap:wrap;gap:12px}}.plots div{{font-size:12px}}</style></head><body><h1>stride report</h1><p>{src}: {} events on {} channels, {:.1} s.</p>",
        d.events,
        d.channels.len(),
        d.span_s,
        src = esc(source)
    );
    if !d.warnings.is_empty() {
        s += "<div class=\"warn\"><b>A partial report:</b><ul>";
        for w in &d.warnings {
            let _ = write!(s, "<li>{}</li>", esc(w));
        }
        s += "</ul></div>";
    }
    if let Some(r) = &d.report {
        let _ = write!(
            s,
            "<p>The simulated world ({}, seed {}): {} touch-downs, {} collisions, {} falls, smallest clearance {:.3} m, smallest ZMP margin {:.3} m, joints at a limit {}.</p>",
            esc(&r.scene),
            r.seed,
            r.touchdowns,
            r.collisions,
            r.falls,
            r.min_clearance,
            r.min_zmp_margin,
            r.limits
        );
    }
    s += "<h2>Top view</h2>";
    match top_view(d) {
        Some(svg) => {
            s += "<p>Obstacles (red), every plan's footsteps (blue outlines), the feet as they touched down (green left, orange right), the body's trace (red line), the goal (circle).</p>";
            s += &svg;
        }
        None => s += "<p>Nothing to draw: no map, obstacles, poses or plans in this log.</p>",
    }
    s += "<h2>Elevation map</h2>";
    match map_png(d) {
        Some((uri, what)) => {
            let _ = write!(
                s,
                "<p>{}</p><img alt=\"elevation map\" src=\"{uri}\" style=\"image-rendering:pixelated;width:600px;border:1px solid #ccc\">",
                esc(&what)
            );
        }
        None => s += "<p>No elevation map in this log.</p>",
    }
    s += "<h2>Joint tracking</h2>";
    let joints: Vec<&String> = d
        .measured
        .keys()
        .filter(|j| d.commanded.contains_key(*j))
        .collect();
    if joints.is_empty() {
        s += "<p>No joint with both commanded rows and measured positions in this log.</p>";
    } else {
        s += "<p>Commanded rows (blue) against the drives' measured positions (orange), rad; below, the error (measured less commanded, red).</p><table><tr><th>joint</th><th>max |error|, rad</th><th>RMS error, rad</th></tr>";
        let mut plots = String::from("<div class=\"plots\">");
        for j in joints {
            let c: Vec<(f64, f64)> = d.commanded[j]
                .iter()
                .map(|(t, p)| (*t as f64 * 1e-6, *p))
                .collect();
            let (svg, max, rms) = joint_plot(&c, &d.measured[j]);
            let _ = write!(
                s,
                "<tr><td>{}</td><td>{max:.4}</td><td>{rms:.4}</td></tr>",
                esc(j)
            );
            let _ = write!(plots, "<div><b>{}</b><br>{svg}</div>", esc(j));
        }
        s += "</table>";
        s += &plots;
        s += "</div>";
    }
    s += "<h2>Latencies</h2>";
    if !d.plan_latency_ms.is_empty() {
        let mut v = d.plan_latency_ms.clone();
        v.sort_by(f64::total_cmp);
        let _ = write!(
            s,
            "<p>From a plan request to its plan ({} pairs): p50 {:.1} ms, p99 {:.1} ms, max {:.1} ms.</p>{}",
            v.len(),
            quantile(&v, 0.5),
            quantile(&v, 0.99),
            v[v.len() - 1],
            histogram(&v, 500.0, 80.0)
        );
    }
    s += "<p>Per channel: arrival at the logger less the message's header stamp (the sender's clock; across hosts their clocks' offset too).</p><table><tr><th>channel</th><th>type</th><th>events</th><th>p50, ms</th><th>p99, ms</th><th>max, ms</th><th>histogram</th></tr>";
    for (name, c) in &d.channels {
        let mut v = c.latency_ms.clone();
        v.sort_by(f64::total_cmp);
        let q = |x: f64| {
            if v.is_empty() {
                "–".to_string()
            } else {
                format!("{:.2}", quantile(&v, x))
            }
        };
        let _ = write!(
            s,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            esc(name),
            c.ty.unwrap_or("unknown"),
            c.count,
            q(0.5),
            q(0.99),
            q(1.0),
            histogram(&v, 200.0, 24.0)
        );
    }
    s += "</table></body></html>\n";
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_plotted_line_keeps_every_columns_peaks_in_few_points() {
        // 10 000 samples over 100 pixel columns, one spike.
        let mut xy: Vec<(f64, f64)> = (0..10_000)
            .map(|k| (k as f64 / 100.0, 50.0 + (k as f64 / 300.0).sin()))
            .collect();
        xy[5_555].1 = 5.0;
        let c = columns(&xy);
        assert!(c.len() <= 202, "{}", c.len());
        assert!(c.contains(&xy[5_555]));
        assert!(c.windows(2).all(|w| w[0].0 <= w[1].0));
        assert_eq!((c[0], c[c.len() - 1]), (xy[0], xy[9_999]));
    }
}
