//! The reference beside a `bench fleet` run (`--orders K`): the same missions (same robots,
//! starts, goals, seeds and people) planned first-come, one robot after another, in `K`
//! orders, each on a fresh schedule and driven jointly as the run is; the least makespan among
//! the orders that brought every robot through is what first-come planning reaches, and the
//! run's makespan is read against it as well as against the robots alone.
//!
//! The lower bound is the robots' makespan alone: no robot of a joint run is faster than its
//! plan alone on the same roadmap. No tighter bound is claimed (docs/benchmarks.md, `bench
//! fleet`).

use std::path::Path;
use std::sync::Arc;

use super::{
    FleetBenchOptions, FleetRow, MemorySchedule, Prepared, arrival_times, joint_run, now_ms,
    plan_in_order, shuffled,
};
use crate::error::BenchError;

/// Most orders `--orders` may ask for: each is a whole fleet planned in turn and driven.
pub const MAX_ORDERS: usize = 24;

/// Mixed into `--seed` for the orders' shuffles, so they differ from `--order-seed`'s with
/// the same value.
const ORDER_SALT: u64 = 0x0f1e_57c0_3e00_0000;

/// Refuses an `--orders` out of range.
pub(super) fn check(opts: &FleetBenchOptions) -> Result<(), BenchError> {
    if opts.orders > MAX_ORDERS {
        return Err(BenchError::BadOption(format!(
            "--orders must lie in [0, {MAX_ORDERS}], got {}",
            opts.orders
        )));
    }
    Ok(())
}

/// The `k`-th order of `n` robots: by robot index for `k` = 0, else shuffled by a seed
/// derived from `seed` and `k`. (With fewer than `k` orderings of the robots some repeat.)
fn order(k: usize, n: usize, seed: u64) -> Vec<usize> {
    if k == 0 {
        (0..n).collect()
    } else {
        shuffled(n, grid::seed::mix(seed ^ ORDER_SALT, k as u64))
    }
}

/// One first-come order: its robots that arrived in its joint run, and its makespan (their
/// last arrival after the common start; 0 where none arrived), seconds.
#[derive(Debug, Clone, Copy)]
struct Order {
    arrived: usize,
    makespan_s: f64,
}

/// The orders of a floor.
#[derive(Debug, Clone, Default)]
pub(super) struct FirstCome {
    orders: Vec<Order>,
    /// Robots that asked.
    robots: usize,
}

impl FirstCome {
    /// The least makespan among the orders that brought every robot through.
    fn best_s(&self) -> Option<f64> {
        self.orders
            .iter()
            .filter(|o| o.arrived == self.robots)
            .map(|o| o.makespan_s)
            .min_by(f64::total_cmp)
    }

    /// The reference's fields of `row` (the run's makespan and alone already in it).
    pub(super) fn fill(&self, row: &mut FleetRow) {
        let best = self.best_s();
        row.first_come_orders = self.orders.len();
        row.first_come_makespans_s = self.orders.iter().map(|o| o.makespan_s).collect();
        row.first_come_arrived = self.orders.iter().map(|o| o.arrived).collect();
        row.best_first_come_makespan_s = best;
        row.makespan_vs_best_first_come = best.filter(|b| *b > 0.0).map(|b| row.makespan_s / b);
        row.makespan_lower_bound_s = row.makespan_alone_s;
    }
}

/// The floor's missions planned first-come in `opts.orders` orders, each on a fresh schedule
/// (the robots standing at their starts first, as in the run), then driven jointly as the
/// run is (the schedule's itineraries, starts not held).
pub(super) fn first_come(
    opts: &FleetBenchOptions,
    floor: &Prepared,
    yaml: &Path,
) -> Result<FirstCome, BenchError> {
    let robots = floor.missions.len();
    let mut orders = Vec::with_capacity(opts.orders);
    for k in 0..opts.orders {
        let schedule = Arc::new(MemorySchedule::default());
        let planner = floor.planner(Some(&schedule));
        let t0 = now_ms() + 60_000;
        let queries = floor.queries(opts, t0, true);
        floor.stand_all(opts, &planner, &queries, t0, yaml)?;
        let planned: Vec<_> = floor
            .runtime
            .block_on(plan_in_order(
                std::slice::from_ref(&planner),
                queries,
                order(k, robots, opts.seed),
            ))
            .into_iter()
            .filter_map(|(_, a)| a.ok())
            .collect();
        let arrivals = arrival_times(&joint_run(&planned, &schedule.all(), None));
        orders.push(Order {
            arrived: arrivals.len(),
            makespan_s: arrivals.iter().copied().fold(0.0, f64::max),
        });
    }
    Ok(FirstCome { orders, robots })
}

/// The orders' makespans under the table, one line per row that has any.
pub(super) fn markdown_lines(rows: &[FleetRow]) -> String {
    let mut md = String::new();
    for r in rows.iter().filter(|r| r.first_come_orders > 0) {
        let each: Vec<String> = r
            .first_come_makespans_s
            .iter()
            .zip(&r.first_come_arrived)
            .map(|(m, a)| format!("{m:.1} s ({a}/{})", r.robots))
            .collect();
        let best = r.best_first_come_makespan_s.map_or_else(
            || "none brought every robot through".to_owned(),
            |b| format!("best {b:.1} s"),
        );
        md.push_str(&format!(
            "\n{} ({}): first-come in {} orders (makespan, arrived): {}; {best}; lower bound {:.1} s (alone)\n",
            r.map,
            r.scenario,
            r.first_come_orders,
            each.join(", "),
            r.makespan_lower_bound_s
        ));
    }
    md
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn order_zero_is_by_index_and_the_others_are_permutations() {
        assert_eq!(order(0, 4, 7), vec![0, 1, 2, 3]);
        for k in 1..6 {
            let mut o = order(k, 6, 7);
            o.sort_unstable();
            assert_eq!(o, (0..6).collect::<Vec<_>>());
        }
        assert_ne!(order(1, 8, 7), order(2, 8, 7));
    }

    #[test]
    fn the_best_is_among_the_orders_that_brought_every_robot_through() {
        let first_come = FirstCome {
            orders: vec![
                Order {
                    arrived: 3,
                    makespan_s: 50.0,
                },
                Order {
                    arrived: 2,
                    makespan_s: 20.0,
                },
                Order {
                    arrived: 3,
                    makespan_s: 40.0,
                },
            ],
            robots: 3,
        };
        assert_eq!(first_come.best_s(), Some(40.0));
        let none = FirstCome {
            orders: vec![Order {
                arrived: 1,
                makespan_s: 9.0,
            }],
            robots: 3,
        };
        assert_eq!(none.best_s(), None);
        assert_eq!(FirstCome::default().best_s(), None);
    }
}
