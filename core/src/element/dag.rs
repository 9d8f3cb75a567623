//! The step as a task graph (issue 42): its work, its critical path, and list schedules of it.
//!
//! A [`TaskGraph`] is a set of tasks, each with a cost (seconds, or any unit) and the tasks it
//! waits for. The chunks of a block's force pass are one (`Schedule::task_graph`: a chunk waits
//! for the chunks sharing a cluster with it that come before it in the schedule's sequence,
//! `Schedule::wait_on`); `flem bench step` adds the node update and the rest of the step after
//! it and measures every cost on one thread.
//!
//! - **Work** `W`: the sum of the costs (one thread's time).
//! - **Critical path** `D`: the costliest chain of waits (no number of threads can finish
//!   sooner).
//! - **Parallelism** `W / D`: the most threads the graph can keep busy on average.
//! - **List schedule** ([`TaskGraph::list_schedule`]): `p` threads, each taking, whenever it is
//!   free, the ready task (every task it waits for done) of smallest priority; its finishing
//!   time, the *makespan*, is within `W / p + D` (Graham's bound), and `W / makespan` is the
//!   simulated speed-up on `p` threads with no cost of waiting or of memory bandwidth.
//!
//! Hand-written (a few dozen lines): the crates for graphs (petgraph) have longest paths of
//! unweighted or edge-weighted graphs but no list scheduler, and the graph is a CSR already.

/// Tasks with costs and the tasks each waits for (CSR).
#[derive(Clone, Debug, Default)]
pub struct TaskGraph {
    /// Cost of each task.
    pub cost: Vec<f64>,
    /// The tasks task `k` waits for: `pred[pred_start[k]..pred_start[k + 1]]`.
    pub pred_start: Vec<u32>,
    pub pred: Vec<u32>,
}

/// The critical path of a graph: its length and its tasks, first to last.
#[derive(Clone, Debug, PartialEq)]
pub struct CriticalPath {
    pub length: f64,
    pub tasks: Vec<u32>,
}

impl TaskGraph {
    /// A graph from each task's cost and the tasks it waits for. `None` when a task waits for
    /// a task that does not exist or the waits have a cycle.
    pub fn new(cost: Vec<f64>, preds: &[Vec<u32>]) -> Option<TaskGraph> {
        if preds.len() != cost.len() {
            return None;
        }
        let mut g = TaskGraph { cost, pred_start: vec![0], pred: Vec::new() };
        for p in preds {
            g.pred.extend_from_slice(p);
            g.pred_start.push(g.pred.len() as u32);
        }
        if g.pred.iter().any(|&p| p as usize >= g.len()) || g.topological().is_none() {
            return None;
        }
        Some(g)
    }

    pub fn len(&self) -> usize {
        self.cost.len()
    }

    pub fn is_empty(&self) -> bool {
        self.cost.is_empty()
    }

    /// The tasks task `k` waits for.
    pub fn preds(&self, k: usize) -> &[u32] {
        &self.pred[self.pred_start[k] as usize..self.pred_start[k + 1] as usize]
    }

    /// The tasks waiting for each task (CSR: start, items).
    fn succs(&self) -> (Vec<u32>, Vec<u32>) {
        let n = self.len();
        let mut start = vec![0u32; n + 1];
        for &p in &self.pred {
            start[p as usize + 1] += 1;
        }
        for k in 0..n {
            start[k + 1] += start[k];
        }
        let mut fill = start.clone();
        let mut items = vec![0u32; self.pred.len()];
        for k in 0..n {
            for &p in self.preds(k) {
                items[fill[p as usize] as usize] = k as u32;
                fill[p as usize] += 1;
            }
        }
        (start, items)
    }

    /// The tasks in an order that keeps every wait (Kahn), `None` on a cycle.
    fn topological(&self) -> Option<Vec<u32>> {
        let n = self.len();
        let (ss, si) = self.succs();
        let mut waits: Vec<u32> = (0..n).map(|k| self.preds(k).len() as u32).collect();
        let mut order: Vec<u32> = (0..n as u32).filter(|&k| waits[k as usize] == 0).collect();
        let mut i = 0;
        while i < order.len() {
            let k = order[i] as usize;
            for &s in &si[ss[k] as usize..ss[k + 1] as usize] {
                waits[s as usize] -= 1;
                if waits[s as usize] == 0 {
                    order.push(s);
                }
            }
            i += 1;
        }
        (order.len() == n).then_some(order)
    }

    /// Total work: the sum of the costs.
    pub fn work(&self) -> f64 {
        self.cost.iter().sum()
    }

    /// The costliest chain of waits (ties: the first found in topological order).
    pub fn critical_path(&self) -> CriticalPath {
        let order = self.topological().expect("a TaskGraph has no cycle (checked by new)");
        let mut finish = vec![0.0f64; self.len()];
        let mut via = vec![u32::MAX; self.len()];
        for &k in &order {
            let k = k as usize;
            let mut start = 0.0;
            for &p in self.preds(k) {
                if finish[p as usize] > start || via[k] == u32::MAX && finish[p as usize] >= start {
                    start = finish[p as usize];
                    via[k] = p;
                }
            }
            finish[k] = start + self.cost[k];
        }
        let Some(mut k) = (0..self.len()).reduce(|a, b| if finish[b] > finish[a] { b } else { a }) else {
            return CriticalPath { length: 0.0, tasks: Vec::new() };
        };
        let length = finish[k];
        let mut tasks = vec![k as u32];
        while via[k] != u32::MAX {
            k = via[k] as usize;
            tasks.push(k as u32);
        }
        tasks.reverse();
        CriticalPath { length, tasks }
    }

    /// Work over critical path (1 for an empty or costless graph).
    pub fn parallelism(&self) -> f64 {
        let d = self.critical_path().length;
        if d > 0.0 {
            self.work() / d
        } else {
            1.0
        }
    }

    /// The makespan of a list schedule on `threads` threads: whenever a thread is free it
    /// starts the ready task of smallest `priority` (ties: smallest index), a task being ready
    /// when every task it waits for is done. No cost of starting or of waiting.
    pub fn list_schedule(&self, threads: usize, priority: &[u32]) -> f64 {
        use std::cmp::Reverse;
        use std::collections::BinaryHeap;
        assert_eq!(priority.len(), self.len(), "one priority per task");
        let (ss, si) = self.succs();
        let mut waits: Vec<u32> = (0..self.len()).map(|k| self.preds(k).len() as u32).collect();
        let mut ready: BinaryHeap<Reverse<(u32, u32)>> = (0..self.len() as u32).filter(|&k| waits[k as usize] == 0).map(|k| Reverse((priority[k as usize], k))).collect();
        // Running tasks by finishing time (f64 bits order as the value for finite non-negative times).
        let mut running: BinaryHeap<Reverse<(u64, u32)>> = BinaryHeap::new();
        let (mut now, mut free) = (0.0f64, threads.max(1));
        loop {
            while free > 0 {
                let Some(Reverse((_, k))) = ready.pop() else { break };
                running.push(Reverse(((now + self.cost[k as usize]).to_bits(), k)));
                free -= 1;
            }
            let Some(Reverse((t, k))) = running.pop() else { break };
            now = f64::from_bits(t);
            free += 1;
            for &s in &si[ss[k as usize] as usize..ss[k as usize + 1] as usize] {
                waits[s as usize] -= 1;
                if waits[s as usize] == 0 {
                    ready.push(Reverse((priority[s as usize], s)));
                }
            }
        }
        now
    }

    /// `self`, then `next` after every task of `self` (each task of `next` that waits for
    /// nothing then waits for the sinks of `self`: the tasks nothing waits for).
    pub fn then(&self, next: &TaskGraph) -> TaskGraph {
        let n = self.len() as u32;
        let (ss, _) = self.succs();
        let sinks: Vec<u32> = (0..n).filter(|&k| ss[k as usize] == ss[k as usize + 1]).collect();
        let mut g = self.clone();
        g.cost.extend_from_slice(&next.cost);
        for k in 0..next.len() {
            if next.preds(k).is_empty() {
                g.pred.extend_from_slice(&sinks);
            } else {
                g.pred.extend(next.preds(k).iter().map(|&p| p + n));
            }
            g.pred_start.push(g.pred.len() as u32);
        }
        g
    }

    /// `costs.len()` independent tasks.
    pub fn independent(costs: Vec<f64>) -> TaskGraph {
        let n = costs.len();
        TaskGraph { cost: costs, pred_start: vec![0; n + 1], pred: Vec::new() }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The graph of hand-computed figures:
    /// ```text
    ///   0 (2) --> 2 (3) --> 4 (1)
    ///   1 (4) --> 3 (1) ----^
    ///         \-> 2
    /// ```
    /// 2 waits for 0 and 1; 3 for 1; 4 for 2 and 3. Work 11. Paths: 0-2-4 = 6, 1-2-4 = 8,
    /// 1-3-4 = 6: the critical path is 1, 2, 4 of length 8, parallelism 11 / 8.
    fn diamond() -> TaskGraph {
        TaskGraph::new(vec![2.0, 4.0, 3.0, 1.0, 1.0], &[vec![], vec![], vec![0, 1], vec![1], vec![2, 3]]).unwrap()
    }

    #[test]
    fn work_critical_path_and_parallelism_by_hand() {
        let g = diamond();
        assert_eq!(g.work(), 11.0);
        assert_eq!(g.critical_path(), CriticalPath { length: 8.0, tasks: vec![1, 2, 4] });
        assert_eq!(g.parallelism(), 11.0 / 8.0);
        // A chain: the critical path is everything, parallelism 1.
        let chain = TaskGraph::new(vec![1.0, 2.0, 3.0], &[vec![], vec![0], vec![1]]).unwrap();
        assert_eq!(chain.critical_path(), CriticalPath { length: 6.0, tasks: vec![0, 1, 2] });
        assert_eq!(chain.parallelism(), 1.0);
        // Independent tasks: the critical path is the costliest one.
        let flat = TaskGraph::independent(vec![1.0, 5.0, 2.0, 2.0]);
        assert_eq!(flat.critical_path(), CriticalPath { length: 5.0, tasks: vec![1] });
        assert_eq!(flat.parallelism(), 2.0);
        assert_eq!(TaskGraph::default().parallelism(), 1.0);
    }

    #[test]
    fn bad_graphs_are_refused() {
        assert!(TaskGraph::new(vec![1.0, 1.0], &[vec![1], vec![0]]).is_none(), "cycle");
        assert!(TaskGraph::new(vec![1.0], &[vec![3]]).is_none(), "no such task");
        assert!(TaskGraph::new(vec![1.0], &[]).is_none(), "one wait list per task");
    }

    /// Makespans worked by hand. Diamond, priority = index. One thread: the work, 11. Two
    /// threads: t=0 start 0 (to 2) and 1 (to 4); t=2 thread free, nothing ready (2 waits for
    /// 1); t=4 start 2 (to 7) and 3 (to 5); t=7 start 4 (to 8): 8 = the critical path. Three
    /// threads: the same, 8. Independent tasks 3, 3, 2, 2, 2 on two threads with priority =
    /// index: 0 and 1 at 0 (to 3), 2 and 3 at 3 (to 5), 4 at 5 (to 7): 7, where the best is 6
    /// (3 + 3 | 2 + 2 + 2): a list schedule is not optimal, only within W / p + D.
    #[test]
    fn list_schedule_makespans_by_hand() {
        let g = diamond();
        let idx: Vec<u32> = (0..5).collect();
        assert_eq!(g.list_schedule(1, &idx), 11.0);
        assert_eq!(g.list_schedule(2, &idx), 8.0);
        assert_eq!(g.list_schedule(3, &idx), 8.0);
        let flat = TaskGraph::independent(vec![3.0, 3.0, 2.0, 2.0, 2.0]);
        assert_eq!(flat.list_schedule(2, &idx), 7.0);
        // Priority 2, 3, 4 first: 2 and 3 at 0 (to 2), 4 at 2 (to 4) beside 0 (to 5), 1 at 4 (to 7): 7.
        assert_eq!(flat.list_schedule(2, &[3, 4, 0, 1, 2]), 7.0);
        assert_eq!(flat.list_schedule(5, &idx), 3.0);
        // Graham's bound on a bigger graph: within W / p + D, never below max(W / p, D).
        let n = 200;
        let preds: Vec<Vec<u32>> = (0..n).map(|k: u32| if k >= 7 { vec![k - 7, k / 3] } else { vec![] }).collect();
        let cost: Vec<f64> = (0..n).map(|k| 1.0 + (k * 37 % 11) as f64).collect();
        let g = TaskGraph::new(cost, &preds).unwrap();
        let (w, d) = (g.work(), g.critical_path().length);
        for p in [1, 2, 4, 16, 64] {
            let m = g.list_schedule(p, &(0..n).collect::<Vec<_>>());
            assert!(m >= (w / p as f64).max(d) - 1e-9 && m <= w / p as f64 + d + 1e-9, "{p} threads: {m} ({w}, {d})");
        }
    }

    /// `then`: the second graph's free tasks wait for the first's sinks. Diamond then two
    /// independent tasks of 2 and 5: the critical path 1, 2, 4, 6 of length 13, work 18.
    #[test]
    fn then_chains_graphs() {
        let g = diamond().then(&TaskGraph::independent(vec![2.0, 5.0]));
        assert_eq!(g.preds(5), &[4]);
        assert_eq!(g.work(), 18.0);
        assert_eq!(g.critical_path(), CriticalPath { length: 13.0, tasks: vec![1, 2, 4, 6] });
        assert_eq!(g.list_schedule(2, &(0..7).collect::<Vec<_>>()), 13.0);
    }
}
