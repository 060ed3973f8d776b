//! The footstep planners' scenes (KAIST's and LOLA's): the thesis's mode and the improved one
//! side by side, through the planners' one interface.

use std::io::Write;
use std::path::Path;
use std::time::{Duration, Instant};

use anyhow::Context;
use stride_footstep::grid::Grid;
use stride_footstep::plan::{Plan, Status};
use stride_footstep::planner::{self, scene_request, Which};
use stride_footstep::scene::Scene;
use stride_footstep::svg;
use stride_node::outln;

use crate::pct;

/// One scene planned in one mode.
pub struct Row {
    /// The scene's name.
    pub scene: String,
    /// "thesis" or "improved".
    pub mode: &'static str,
    /// The last plan.
    pub plan: Plan,
    /// Whole-plan times, µs.
    pub total: Vec<f64>,
    /// Times to the first plan, µs.
    pub first: Vec<f64>,
    /// What the thesis reports for the scene.
    pub reference: String,
}

/// Plans `scene` in both modes, `repeats` times each (the improved mode within `budget`; the
/// thesis's modes get the same), writing SVGs to `out` unless `no_svg`.
pub fn run(
    scene: &Scene,
    repeats: usize,
    budget: Duration,
    out: &Path,
    no_svg: bool,
) -> anyhow::Result<Vec<Row>> {
    let grid = Grid::of_scene(scene).with_context(|| format!("scene {}", scene.name))?;
    let unit = if planner::for_scene(scene) == Which::Kaist {
        "J"
    } else {
        "(weighted m)"
    };
    let mut rows = Vec::new();
    for (faithful, name) in [(true, "thesis"), (false, "improved")] {
        let mut req = scene_request(scene, faithful);
        // LOLA's receding-horizon scene plans seven steps at a time (the thesis's horizon).
        if scene.name.contains("receding") {
            req.horizon = Some(7);
        }
        let (mut total, mut first) = (Vec::new(), Vec::new());
        let mut last = None;
        for _ in 0..repeats.max(1) {
            let t = Instant::now();
            let p = planner::plan(&req, scene, budget);
            let all = t.elapsed();
            total.push(all.as_secs_f64() * 1e6);
            let f = p.stats.first_plan.map_or(all, |f| f + p.stats.prepare);
            first.push(f.as_secs_f64() * 1e6);
            last = Some(p);
        }
        let plan = last.expect("one run");
        if !no_svg {
            let title = format!("{} ({name})", scene.name);
            let picture =
                svg::render_grid(&title, &grid, scene.start.p(), scene.goal.p(), &plan, unit);
            let path = out.join(format!("{}-{name}.svg", scene.name));
            std::fs::write(&path, picture)
                .with_context(|| format!("writing {}", path.display()))?;
        }
        rows.push(Row {
            scene: scene.name.clone(),
            mode: name,
            plan,
            total,
            first,
            reference: scene.reference.clone(),
        });
    }
    Ok(rows)
}

/// Writes every metric, a row per scene and mode.
pub fn write_csv(path: &Path, rows: &mut [Row]) -> anyhow::Result<()> {
    let mut f = std::io::BufWriter::new(
        std::fs::File::create(path).with_context(|| format!("writing {}", path.display()))?,
    );
    writeln!(
        f,
        "scene,mode,status,cost,steps,expansions,first_plan_expansions,generated,collision_queries,bound,prepare_us,search_us,first_plan_p50_us,first_plan_p99_us,total_p50_us,total_p99_us"
    )?;
    for r in rows {
        let s = r.plan.stats;
        writeln!(
            f,
            "{},{},{},{:.1},{},{},{},{},{},{},{:.1},{:.1},{:.1},{:.1},{:.1},{:.1}",
            r.scene,
            r.mode,
            r.plan.status.name(),
            r.plan.cost,
            r.plan.steps.len().saturating_sub(2),
            s.expansions,
            s.first_plan_expansions
                .map_or(String::new(), |e| e.to_string()),
            s.generated,
            s.collision_queries,
            r.plan.bound.map_or(String::new(), |b| format!("{b}")),
            s.prepare.as_secs_f64() * 1e6,
            s.search.as_secs_f64() * 1e6,
            pct(&mut r.first, 50.0),
            pct(&mut r.first, 99.0),
            pct(&mut r.total, 50.0),
            pct(&mut r.total, 99.0),
        )?;
    }
    Ok(())
}

fn ms(us: f64) -> String {
    if us < 1000.0 {
        format!("{us:.0} µs")
    } else {
        format!("{:.1} ms", us / 1000.0)
    }
}

/// The side-by-side table, and the bars' verdicts.
pub fn print_table(rows: &mut [Row], repeats: usize, budget: Duration) -> std::io::Result<()> {
    outln!("| scene | thesis: status | cost | steps | expansions | preparation | p50 / p99 | improved: status | cost | / thesis | steps | expansions to first plan | / thesis | first plan p50 / p99 | bound at the budget | expansions | p50 / p99 | the thesis reports |")?;
    outln!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")?;
    let (mut worse, mut over_half, mut slow_p50, mut slow_p99, mut fails) = (0, 0, 0, 0, 0);
    // How many comparisons each verdict rests on, and the refusals that were right.
    let (mut cost_pairs, mut exp_pairs, mut refusals) = (0, 0, 0);
    let mut worst_first = (0.0f64, 0.0f64);
    for pair in rows.chunks_mut(2) {
        let [t, i] = pair else { continue };
        let ok = |p: &Plan| p.status == Status::Ok;
        let vs_cost = if ok(&t.plan) && ok(&i.plan) {
            cost_pairs += 1;
            let r = i.plan.cost / t.plan.cost;
            if r > 1.005 {
                worse += 1;
            }
            format!("{r:.4}")
        } else {
            "—".into()
        };
        let first_exp = i.plan.stats.first_plan_expansions;
        let vs_exp = match (ok(&t.plan), first_exp) {
            (true, Some(e)) => {
                exp_pairs += 1;
                let r = e as f64 / t.plan.stats.expansions as f64;
                if r > 0.5 {
                    over_half += 1;
                }
                format!("{r:.3}")
            }
            _ => "—".into(),
        };
        let horizon = i.plan.status == Status::Partial && i.plan.detail == "the horizon";
        // A refusal is right when the goal is in collision or outside the map, or when
        // neither mode found a way; a failure is the improved mode without a plan where the
        // thesis's found one, or out of budget.
        let refusal = matches!(
            i.plan.status,
            Status::GoalInCollision | Status::StartInCollision | Status::GoalOutsideMap
        ) || (i.plan.status == Status::NoPath && !ok(&t.plan));
        if refusal {
            refusals += 1;
        } else if !ok(&i.plan) && !horizon {
            fails += 1;
        }
        let (f50, f99) = (pct(&mut i.first, 50.0), pct(&mut i.first, 99.0));
        worst_first = (worst_first.0.max(f50), worst_first.1.max(f99));
        if f50 > 10_000.0 {
            slow_p50 += 1;
        }
        if f99 > 50_000.0 {
            slow_p99 += 1;
        }
        let cost = |p: &Plan| {
            if p.cost.is_finite() && p.cost >= 100.0 {
                format!("{:.0}", p.cost)
            } else if p.cost.is_finite() {
                format!("{:.3}", p.cost)
            } else {
                "—".into()
            }
        };
        outln!(
            "| {} | {} | {} | {} | {} | {} | {} / {} | {} | {} | {} | {} | {} | {} | {} / {} | {} | {} | {} / {} | {} |",
            t.scene,
            t.plan.status.name(),
            cost(&t.plan),
            t.plan.steps.len().saturating_sub(2),
            t.plan.stats.expansions,
            ms(t.plan.stats.prepare.as_secs_f64() * 1e6),
            ms(pct(&mut t.total, 50.0)),
            ms(pct(&mut t.total, 99.0)),
            i.plan.status.name(),
            cost(&i.plan),
            vs_cost,
            i.plan.steps.len().saturating_sub(2),
            first_exp.map_or("—".into(), |e| e.to_string()),
            vs_exp,
            ms(f50),
            ms(f99),
            i.plan.bound.map_or("—".into(), |b| format!("{b}")),
            i.plan.stats.expansions,
            ms(pct(&mut i.total, 50.0)),
            ms(pct(&mut i.total, 99.0)),
            t.reference,
        )?;
    }
    outln!()?;
    let of = |n: usize, pairs: usize| {
        if pairs == 0 {
            format!("not shown (0 of {} scenes comparable)", rows.len() / 2)
        } else {
            format!("{n} of {pairs} comparable")
        }
    };
    outln!(
        "{} scenes, {repeats} runs each, budget {} ms: improved failures {fails}, right refusals \
         (goal in collision or outside the map, no way in either mode) {refusals}; dearer than \
         the thesis's plan by over 0.5 %: {}; first plan needing over half the thesis's \
         expansions: {}; first plan p50 over 10 ms {slow_p50} (worst {}), p99 over 50 ms \
         {slow_p99} (worst {}).",
        rows.len() / 2,
        budget.as_millis(),
        of(worse, cost_pairs),
        of(over_half, exp_pairs),
        ms(worst_first.0),
        ms(worst_first.1),
    )?;
    Ok(())
}
