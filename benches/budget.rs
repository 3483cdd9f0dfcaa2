//! Each budget strategy at 1k, 10k, 100k and 1M objects with 8-level ladders.
//!
//! Objects come grouped by type in ascending complexity, as the ECS stage gathers them,
//! so Robin Hood runs its O(n) path. The incremental strategies start from their own
//! answer to the previous frame, which is how they run in practice.
//!
//! `cargo bench --bench budget`; criterion reports time per iteration and objects/s.

use std::hint::black_box;
use std::time::Duration;

use bevy_sherwood::budget::*;
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};

#[path = "../tests/common/mod.rs"]
mod common;

const LEVELS: usize = 8;
const TYPES: usize = 3;

/// A deterministic frame: `n` objects of three types, each with an 8-level ladder whose
/// costs halve per level, scaled by a per-object projected-area factor.
fn frame(n: usize) -> BudgetProblem {
    let mut next = common::unit_noise();
    let mut problem = BudgetProblem::with_capacity(n, LEVELS);
    let mut ladder = [Level::default(); LEVELS];
    for t in 0..TYPES {
        let best = 1.0e-4 * (1 << (2 * t)) as f32; // complexity of the type
        for _ in 0..n / TYPES + usize::from(t < n % TYPES) {
            let area = 0.05 + next();
            for (k, level) in ladder.iter_mut().enumerate() {
                let cost = best * area / (1 << k) as f32;
                level.cost = cost;
                level.benefit = area * (1.0 - 0.5 / (LEVELS - k) as f32);
            }
            let desc = ObjectDesc {
                value: area / (1.0 + 20.0 * next()),
                complexity: best,
                previous: PreviousSelection::New,
            };
            problem.push_object(desc, &ladder).unwrap();
        }
    }
    problem
}

/// The same frame seeded with `strategy`'s own answer to it.
fn warm(problem: &BudgetProblem, strategy: &mut dyn BudgetStrategy, time: f32) -> BudgetProblem {
    let mut out = Vec::new();
    strategy.distribute(problem, time, &mut out);
    let mut warm = BudgetProblem::with_capacity(problem.len(), LEVELS);
    for (i, a) in out.iter().enumerate() {
        let desc = ObjectDesc {
            value: problem.values()[i],
            complexity: problem.complexities()[i],
            previous: a
                .level
                .map_or(PreviousSelection::Dropped, PreviousSelection::Level),
        };
        warm.push_object(desc, problem.ladder(i)).unwrap();
    }
    warm
}

fn strategies(c: &mut Criterion) {
    let mut group = c.benchmark_group("strategy");
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(4));
    group.sample_size(10);
    for n in [1_000, 10_000, 100_000, 1_000_000] {
        let cold = frame(n);
        // About a third of what full detail would cost: the budget binds.
        let full: f32 = (0..n).map(|i| cold.ladder(i)[0].cost).sum();
        let time = full / 3.0;
        group.throughput(Throughput::Elements(n as u64));
        let mut out = Vec::with_capacity(n);
        let makers: [(&str, fn() -> Box<dyn BudgetStrategy>, bool); 5] = [
            ("robin_hood", || Box::new(RobinHood::new()), false),
            (
                "funkhouser_greedy",
                || Box::new(FunkhouserSequin::new()),
                false,
            ),
            (
                "funkhouser_incremental",
                || Box::new(FunkhouserIncremental::new(0.1)),
                true,
            ),
            ("triangle_budget", || Box::new(TriangleBudget::new()), true),
            ("hierarchical", || Box::new(HierarchicalLod::new()), true),
        ];
        for (name, make, incremental) in makers {
            let mut strategy = make();
            let problem = if incremental {
                warm(&cold, strategy.as_mut(), time)
            } else {
                cold.clone()
            };
            group.bench_with_input(BenchmarkId::new(name, n), &problem, |b, p| {
                b.iter(|| black_box(strategy.distribute(p, time, &mut out)));
            });
        }
    }
    group.finish();
}

criterion_group!(benches, strategies);
criterion_main!(benches);
