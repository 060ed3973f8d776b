//! R20: Archie's walk primitives and modified foot placement (eqs 9-26, 95) against their
//! defining properties and a numeric minimiser.

use stride_gait::lipm::{footsteps, walk, Faithful, LipmConfig, Pendulum, State, WalkParam, G};

fn pendulum(a: f64, b: f64) -> Pendulum {
    Pendulum::new(LipmConfig {
        z_c: 0.62,
        t_sup: 1.0,
        g: G,
        a,
        b,
        faithful: Faithful::default(),
    })
    .unwrap()
}

/// Table 9: five steps of (s_x, s_y).
fn table_9() -> Vec<WalkParam> {
    [
        (0.0, 0.25),
        (0.4, 0.25),
        (0.4, 0.25),
        (0.4, 0.25),
        (0.0, 0.25),
    ]
    .iter()
    .map(|&(sx, sy)| WalkParam { sx, sy, theta: 0.0 })
    .collect()
}

#[test]
fn eq_11_the_primitive_ends_where_it_mirrors_its_start() {
    let p = pendulum(10.0, 1.0);
    for &(sx, sy) in &[(0.3, 0.2), (0.0, 0.25), (-0.1, 0.18)] {
        let (bar, vbar) = p.primitive(0, WalkParam { sx, sy, theta: 0.0 });
        // x from (−x̄, v̄x) to (x̄, v̄x); y from (ȳ, −v̄y) to (ȳ, v̄y), about the foot at 0.
        let x = p.advance(-bar[0], vbar[0], 0.0, 1.0);
        let y = p.advance(bar[1], -vbar[1], 0.0, 1.0);
        assert!(
            (x[0] - bar[0]).abs() < 1e-12 && (x[1] - vbar[0]).abs() < 1e-12,
            "{x:?}"
        );
        assert!(
            (y[0] - bar[1]).abs() < 1e-12 && (y[1] - vbar[1]).abs() < 1e-12,
            "{y:?}"
        );
    }
}

/// The cost of eq 22 for a foot at `pf`, from (`xi`, `vi`) with the target (`xd`, `vd`).
fn cost(p: &Pendulum, from: (f64, f64), to: (f64, f64), pf: f64) -> f64 {
    let c = p.config();
    let e = p.advance(from.0, from.1, pf, 1.0);
    c.a * (to.0 - e[0]).powi(2) + c.b * (to.1 - e[1]).powi(2)
}

#[test]
fn eq_24_is_the_minimiser_a_numeric_search_finds() {
    for &(a, b) in &[(10.0, 1.0), (1.0, 1.0), (1.0, 10.0)] {
        let p = pendulum(a, b);
        for &(xi, vi, xd, vd) in &[
            (0.1, 0.3, 0.5, 0.4),
            (-0.2, 0.1, 0.2, -0.3),
            (0.0, 0.0, 0.1, 0.2),
        ] {
            let closed = p.foot_placement(xi, vi, xd, vd);
            // Golden-section search over the foot's place.
            let (mut lo, mut hi) = (-5.0f64, 5.0f64);
            let r = (5f64.sqrt() - 1.0) / 2.0;
            for _ in 0..200 {
                let (m1, m2) = (hi - r * (hi - lo), lo + r * (hi - lo));
                if cost(&p, (xi, vi), (xd, vd), m1) < cost(&p, (xi, vi), (xd, vd), m2) {
                    hi = m2;
                } else {
                    lo = m1;
                }
            }
            let numeric = (lo + hi) / 2.0;
            assert!(
                (closed - numeric).abs() < 1e-7,
                "a {a} b {b}: {closed} vs {numeric}"
            );
        }
    }
}

#[test]
fn with_a_huge_position_weight_the_step_ends_on_its_target() {
    let p = pendulum(1e12, 1.0);
    let (xi, vi, xd, vd) = (0.1, 0.3, 0.5, 0.4);
    let f = p.foot_placement(xi, vi, xd, vd);
    let end = p.advance(xi, vi, f, 1.0);
    assert!((end[0] - xd).abs() < 1e-9, "{end:?}");
}

#[test]
fn eq_95_gives_table_9s_footsteps() {
    let f = footsteps(&table_9(), [0.0, 0.0]);
    let want = [
        [0.0, 0.25],
        [0.4, 0.0],
        [0.8, 0.25],
        [1.2, 0.0],
        [1.2, 0.25],
    ];
    assert_eq!(f.len(), 5);
    for (g, w) in f.iter().zip(&want) {
        assert!(
            (g[0] - w[0]).abs() < 1e-12 && (g[1] - w[1]).abs() < 1e-12,
            "{f:?}"
        );
    }
}

#[test]
fn the_walk_places_table_9s_feet_near_the_plan_and_joins_its_periods() {
    let p = pendulum(10.0, 1.0);
    let params = table_9();
    // The initial state chosen (the thesis gives none): the first primitive's, the COM
    // halfway between the feet (the left foot at (0, 0.25)) moving toward the support foot.
    let (bar, vbar) = p.primitive(0, params[0]);
    let s = walk(
        &p,
        &params,
        [0.0, 0.0],
        State {
            x: [-bar[0], bar[1]],
            v: [vbar[0], -vbar[1]],
        },
    );
    assert_eq!(s[0].start.x, [0.0, 0.125]);
    assert_eq!(s.len(), 6);
    // Each period starts where the last ended (position and velocity continuous).
    for w in s.windows(2) {
        assert_eq!(w[0].end, w[1].start);
    }
    // The modified placement stays near the nominal footsteps.
    for (k, sup) in s.iter().enumerate().skip(1) {
        let d = (sup.foot[0] - sup.nominal[0]).hypot(sup.foot[1] - sup.nominal[1]);
        assert!(d < 0.01, "step {k}: placed {d} m from the plan");
    }
}

#[test]
fn eq_7_as_printed_differs() {
    let ok = pendulum(10.0, 1.0);
    let printed = Pendulum::new(LipmConfig {
        faithful: Faithful { eq_7: true },
        ..*ok.config()
    })
    .unwrap();
    let (a, b) = (
        ok.advance(0.1, 0.3, 0.0, 0.5),
        printed.advance(0.1, 0.3, 0.0, 0.5),
    );
    assert_eq!(a[0], b[0]);
    assert!((a[1] - b[1]).abs() > 0.1, "{a:?} {b:?}");
}
