//! The one weighted A* pass of the footstep searches (KAIST's and LOLA's): a tree search, or
//! with duplicate detection on a lattice, pruned by the cost of the best plan so far. The
//! anytime loop around it is [`crate::plan::anytime`]; what a state is, its heuristic, its
//! successors and when to stop are the planner's ([`Space`]).

use std::collections::{BinaryHeap, HashMap};
use std::hash::Hash;

use crate::plan::{Entry, Stats};

/// A state the pass reached: how much it cost, how many steps from the root, and from where.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Reached<S> {
    /// The state.
    pub state: S,
    /// The cost from the root.
    pub g: f64,
    /// Steps from the root.
    pub depth: usize,
    /// The state it was reached from (`None` for the root).
    pub parent: Option<usize>,
}

/// A successor: the steps to it, each a state and the step's cost, and its heuristic if the
/// planner already knows it. Steps before the last are steps of the plan that the pass never
/// expands (a walk of several strides taken as one successor).
pub(crate) struct Successor<S> {
    /// The steps, the successor last.
    pub steps: Vec<(S, f64)>,
    /// The successor's heuristic, when known.
    pub h: Option<f64>,
}

/// What a planner's search space gives the pass.
pub(crate) trait Space {
    /// A node of the search (the feet as they stand).
    type State: Copy;
    /// A state's lattice cell, for duplicate detection.
    type Key: Hash + Eq;
    /// How a state ends the search (at the goal, at a horizon).
    type Goal;
    /// The heuristic of `s`.
    fn h(&self, s: &Self::State) -> f64;
    /// The lattice cell of `s` for cells of (position, yaw in degrees).
    fn key(&self, s: &Self::State, cells: (f64, f64)) -> Self::Key;
    /// Whether `s`, reached in `depth` steps, ends the search.
    fn goal(&self, s: &Self::State, depth: usize) -> Option<Self::Goal>;
    /// Why the pass stops before its next expansion (after `expansions` so far), if it does:
    /// the expansion cap, a cancel, the budget.
    fn stop(&self, expansions: u64) -> Option<&'static str>;
    /// The successors of `s`, whose heuristic is `h`.
    fn successors(&self, s: &Self::State, h: f64, stats: &mut Stats)
        -> Vec<Successor<Self::State>>;
}

/// How a pass ended.
pub(crate) enum End<G> {
    /// A state that ends the search: its index, and how.
    Found(usize, G),
    /// Nothing left to expand below the incumbent.
    Exhausted,
    /// Stopped, with why.
    Stopped(&'static str),
}

/// A pass's end, every state it reached, and the state of least heuristic it expanded when
/// that was below the `nearer` it was given (its heuristic and index).
pub(crate) struct Pass<S, G> {
    /// How it ended.
    pub end: End<G>,
    /// The states reached, the root first.
    pub reached: Vec<Reached<S>>,
    /// The expanded state nearest the goal by the heuristic, if below the bar.
    pub nearest: Option<(f64, usize)>,
}

/// One weighted A* pass from `root` of `weight` on lattice `cells` (duplicate detection only
/// when `lattice`), pruned by `incumbent`: a state kept only while its cost and heuristic stay
/// below it. A lattice cell reached again more cheaply is expanded again (reopening), so a pass
/// of weight w stays within w of the optimum although a heuristic need not be consistent.
pub(crate) fn pass<P: Space>(
    space: &P,
    root: P::State,
    (weight, cells): (f64, (f64, f64)),
    lattice: bool,
    incumbent: f64,
    nearer: f64,
    stats: &mut Stats,
) -> Pass<P::State, P::Goal> {
    let h0 = space.h(&root);
    let mut reached = vec![Reached {
        state: root,
        g: 0.0,
        depth: 0,
        parent: None,
    }];
    let mut order = 0u64;
    let mut open = BinaryHeap::from([Entry {
        f: weight * h0,
        h: h0,
        order,
        node: 0,
    }]);
    // The cheapest way to each lattice cell so far.
    let mut best_g: HashMap<P::Key, f64> = HashMap::new();
    best_g.insert(space.key(&root, cells), 0.0);
    let mut nearest = None;
    let mut bar = nearer;
    let end = loop {
        let Some(Entry { node: i, h: hn, .. }) = open.pop() else {
            break End::Exhausted;
        };
        let n = reached[i];
        if lattice
            && best_g
                .get(&space.key(&n.state, cells))
                .is_some_and(|&b| n.g > b)
        {
            continue;
        }
        if let Some(goal) = space.goal(&n.state, n.depth) {
            break End::Found(i, goal);
        }
        if hn < bar {
            bar = hn;
            nearest = Some((hn, i));
        }
        if let Some(why) = space.stop(stats.expansions) {
            break End::Stopped(why);
        }
        stats.expansions += 1;
        for Successor { steps, h } in space.successors(&n.state, hn, stats) {
            let Some(&(last, _)) = steps.last() else {
                continue;
            };
            let g = steps.iter().fold(n.g, |g, s| g + s.1);
            let key = space.key(&last, cells);
            if lattice && best_g.get(&key).is_some_and(|&b| b <= g) {
                continue;
            }
            let hc = h.unwrap_or_else(|| space.h(&last));
            if g + hc >= incumbent {
                continue;
            }
            // Only a state kept holds its cell: one pruned by the incumbent would shut out
            // a dearer state there whose heuristic is lower.
            if lattice {
                best_g.insert(key, g);
            }
            let (mut parent, mut at) = (i, n);
            for (state, c) in steps {
                at = Reached {
                    state,
                    g: at.g + c,
                    depth: at.depth + 1,
                    parent: Some(parent),
                };
                reached.push(at);
                parent = reached.len() - 1;
            }
            order += 1;
            open.push(Entry {
                f: at.g + weight * hc,
                h: hc,
                order,
                node: parent,
            });
        }
    };
    Pass {
        end,
        reached,
        nearest,
    }
}

/// The states from the root to `end`.
pub(crate) fn trace<S: Copy>(reached: &[Reached<S>], end: usize) -> Vec<S> {
    let mut states = Vec::new();
    let mut at = Some(end);
    while let Some(i) = at {
        states.push(reached[i].state);
        at = reached[i].parent;
    }
    states.reverse();
    states
}
