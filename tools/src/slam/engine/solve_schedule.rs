//! When the engine's incremental solves run: at every change of the
//! accepted loops on a short mission, at most every few nodes on a long
//! one.
//!
//! An incremental solve is a solve of the whole graph, whose cost grows
//! with the nodes; run at every change (which on a slow or long mission
//! means nearly every node) the solves alone grow with the square of the
//! mission. From [`EVERY_CHANGE_NODES`] nodes on, a change at node `k` is
//! solved only when at least `1 + k / EVERY_CHANGE_NODES` nodes have
//! passed since the last solve (changes in between wait, and are solved at
//! the first node that is due); the solves then cost about as much per
//! node as on a mission of `EVERY_CHANGE_NODES` nodes. Several solves at
//! the node that is due (the retries of deferred candidates) all run.
//! Below that every change is solved at once, as before the schedule.
//!
//! What waits: the estimate that gates and places the next candidates, and
//! the online estimate emitted, lag the accepted loops by at most that
//! many nodes; the final solve is unaffected.
//!
//! The online engine's view (the graph solved with the newest node's
//! edges, emitted when the estimate itself was not solved at that node)
//! follows the same rule without a change to wait for: every node below
//! [`EVERY_CHANGE_NODES`], then every `1 + k / EVERY_CHANGE_NODES`-th
//! ([`view_due`]); in between, the last view is extended by the
//! estimate's relative poses.

/// Nodes up to which every change of the accepted loops is solved at once.
pub const EVERY_CHANGE_NODES: usize = 256;

/// Whether the online view is solved at node `k` (see the module doc).
pub fn view_due(k: usize) -> bool {
    k.is_multiple_of(1 + k / EVERY_CHANGE_NODES)
}

/// The schedule's state.
#[derive(Clone, Debug, Default)]
pub struct SolveSchedule {
    /// The node at which the last solve ran.
    last: Option<usize>,
    /// A change of the accepted loops not solved yet.
    pending: bool,
}

impl SolveSchedule {
    /// A change of the accepted loops at node `k`: whether to solve now
    /// (else it waits).
    pub fn on_change(&mut self, k: usize) -> bool {
        self.pending = true;
        self.solve_if_due(k)
    }

    /// After node `k`'s loop closing: whether a change that waited is due.
    pub fn after_node(&mut self, k: usize) -> bool {
        self.pending && self.solve_if_due(k)
    }

    fn solve_if_due(&mut self, k: usize) -> bool {
        let interval = 1 + k / EVERY_CHANGE_NODES;
        let due = self.last.is_none_or(|l| l == k || k >= l + interval);
        if due {
            self.last = Some(k);
            self.pending = false;
        }
        due
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn short_missions_solve_every_change_at_once() {
        let mut s = SolveSchedule::default();
        for k in 0..EVERY_CHANGE_NODES {
            assert!(s.on_change(k), "node {k}");
            assert!(s.on_change(k), "retry at node {k}");
            assert!(!s.after_node(k));
        }
    }

    #[test]
    fn the_online_view_is_solved_at_every_node_then_every_few() {
        assert!((0..EVERY_CHANGE_NODES).all(view_due));
        let k0 = 3 * EVERY_CHANGE_NODES; // interval 4
        let due: Vec<bool> = (k0..k0 + 8).map(view_due).collect();
        assert_eq!(due, [true, false, false, false, true, false, false, false]);
    }

    #[test]
    fn long_missions_solve_changes_every_few_nodes_and_nothing_waits_forever() {
        let mut s = SolveSchedule::default();
        let k0 = 3 * EVERY_CHANGE_NODES; // interval 4
        assert!(s.on_change(k0));
        assert!(s.on_change(k0), "retries at the node that is due");
        assert!(!s.on_change(k0 + 1));
        assert!(!s.after_node(k0 + 2));
        assert!(!s.on_change(k0 + 3));
        // Due again four nodes on, with no new change: the waiting one.
        assert!(s.after_node(k0 + 4));
        assert!(!s.after_node(k0 + 5), "nothing waits");
        assert!(!s.after_node(k0 + 9));
        assert!(s.on_change(k0 + 9));
    }
}
