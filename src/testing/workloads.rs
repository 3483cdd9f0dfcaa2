//! Pieces of the crate's internal work set up and ready to time: what the benches under
//! `benches/` run, without the internals they exercise being public. Each is built from
//! fixed, deterministic inputs, so a run measures the same work every time.

use std::hint::black_box;

use bevy::math::{Affine3A, Mat4, Quat, Vec3};

use crate::budget::{
    BudgetProblem, BudgetStrategy, FunkhouserIncremental, FunkhouserSequin, HierarchicalLod, Level,
    ObjectDesc, PreviousSelection, RobinHood, TriangleBudget,
};
use crate::cost::{Calibration, PrimitiveCosts};
use crate::culling::{
    BoxHierarchy, CullInstance, CullResult, CullShape, FrustumPlanes, InstanceVisibility,
    MovedShapes, cull_brute_force,
};
use crate::draw::TreeDrawList;
use crate::lod::select::{self, LeafMethod, TreeView};
use crate::tree::{BoundingSphere, Bounds, PixelRange, Projection, TreeModel};
use crate::wind::{AssociationRule, WindRig, associate, moved_bounds, ring_offsets};

use super::unit_noise;

/// One piece of work, ready to run again and again.
pub struct Workload {
    /// Its name within its bench group, e.g. `robin_hood/10000`.
    pub name: String,
    /// How many elements (objects, instances, trees) one run handles: criterion's
    /// throughput.
    pub elements: u64,
    /// Something to print once before timing (what the inputs are), if anything.
    pub note: Option<String>,
    work: Box<dyn FnMut()>,
}

impl Workload {
    fn new(name: impl Into<String>, elements: u64, work: impl FnMut() + 'static) -> Self {
        Self {
            name: name.into(),
            elements,
            note: None,
            work: Box::new(work),
        }
    }

    /// Does the work once.
    pub fn run(&mut self) {
        (self.work)();
    }
}

/// Each budget strategy on one frame of `objects` objects with 8-level ladders, about a
/// third of what full detail would cost to draw. Objects come grouped by type in
/// ascending complexity, as the Value stage gathers them, so Robin Hood runs its O(n)
/// path; the incremental strategies start from their own answer to the same frame, which
/// is how they run in practice.
pub fn budget_strategies(objects: usize) -> Vec<Workload> {
    const LEVELS: usize = 8;
    let cold = budget_frame(objects, LEVELS);
    let full: f32 = (0..objects).map(|i| cold.ladder(i)[0].cost).sum();
    let time = full / 3.0;
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
    makers
        .into_iter()
        .map(|(name, make, incremental)| {
            let mut strategy = make();
            let problem = if incremental {
                warm_frame(&cold, strategy.as_mut(), time, LEVELS)
            } else {
                cold.clone()
            };
            let mut out = Vec::with_capacity(objects);
            Workload::new(format!("{name}/{objects}"), objects as u64, move || {
                black_box(strategy.distribute(&problem, time, &mut out));
            })
        })
        .collect()
}

/// A deterministic frame: `n` objects of three types, each with a ladder whose costs
/// halve per level, scaled by a per-object projected-area factor.
fn budget_frame(n: usize, levels: usize) -> BudgetProblem {
    const TYPES: usize = 3;
    let mut next = unit_noise();
    let mut problem = BudgetProblem::with_capacity(n, levels);
    let mut ladder = vec![Level::default(); levels];
    for t in 0..TYPES {
        let best = 1.0e-4 * (1 << (2 * t)) as f32;
        for _ in 0..n / TYPES + usize::from(t < n % TYPES) {
            let area = 0.05 + next();
            for (k, level) in ladder.iter_mut().enumerate() {
                level.cost = best * area / (1 << k) as f32;
                level.benefit = area * (1.0 - 0.5 / (levels - k) as f32);
            }
            let desc = ObjectDesc {
                value: area / (1.0 + 20.0 * next()),
                complexity: best,
                previous: PreviousSelection::New,
            };
            problem
                .push_object(desc, &ladder)
                .expect("the synthetic frame is valid");
        }
    }
    problem
}

/// `problem` seeded with `strategy`'s own answer to it.
fn warm_frame(
    problem: &BudgetProblem,
    strategy: &mut dyn BudgetStrategy,
    time: f32,
    levels: usize,
) -> BudgetProblem {
    let mut out = Vec::new();
    strategy.distribute(problem, time, &mut out);
    let mut warm = BudgetProblem::with_capacity(problem.len(), levels);
    for (i, a) in out.iter().enumerate() {
        let desc = ObjectDesc {
            value: problem.values()[i],
            complexity: problem.complexities()[i],
            previous: a
                .level
                .map_or(PreviousSelection::Dropped, PreviousSelection::Level),
        };
        warm.push_object(desc, problem.ladder(i))
            .expect("the synthetic frame is valid");
    }
    warm
}

/// Culling 100 000 instances (three tree shapes, a 2 000-unit square) seen from the
/// forest's edge: brute force, then the box hierarchy at depths 3 to 7.
pub fn culling() -> Vec<Workload> {
    const SIZE: f32 = 2000.0;
    const INSTANCES: usize = 100_000;
    let shapes = culling_shapes();
    let instances = culling_forest(INSTANCES, SIZE);
    // Bevy's reverse-Z infinite projection, looking across the forest.
    let planes = FrustumPlanes::from_clip_from_world(
        Mat4::perspective_infinite_reverse_rh(1.0, 16.0 / 9.0, 0.1)
            * Mat4::look_at_rh(
                Vec3::new(-50.0, 30.0, SIZE / 2.0),
                Vec3::new(SIZE, 0.0, SIZE * 0.6),
                Vec3::Y,
            ),
    );
    let area = Bounds {
        min: Vec3::ZERO,
        max: Vec3::new(SIZE, 10.0, SIZE),
    };
    let mut workloads = vec![{
        let (instances, shapes) = (instances.clone(), shapes.clone());
        let mut result = CullResult::default();
        Workload::new("brute_force", INSTANCES as u64, move || {
            cull_brute_force(
                &planes,
                &instances,
                &shapes,
                &MovedShapes::default(),
                black_box(&mut result),
            );
        })
    }];
    for depth in [3, 4, 5, 6, 7] {
        let (instances, shapes) = (instances.clone(), shapes.clone());
        let mut hierarchy = BoxHierarchy::build(depth, &area, &instances, &shapes);
        let mut result = CullResult::default();
        let none = MovedShapes::default();
        hierarchy.cull(&planes, &instances, &shapes, &none, &mut result);
        let visible = result
            .visibility
            .iter()
            .filter(|v| **v != InstanceVisibility::Invisible)
            .count();
        let mut workload = Workload::new(format!("hierarchy/{depth}"), INSTANCES as u64, {
            move || hierarchy.cull(&planes, &instances, &shapes, &none, black_box(&mut result))
        });
        workload.note = Some(format!(
            "depth {depth}: {visible} of {INSTANCES} instances visible"
        ));
        workloads.push(workload);
    }
    workloads
}

fn culling_shapes() -> Vec<CullShape> {
    [(6.0, 12), (8.0, 21), (9.0, 24)]
        .iter()
        .map(|&(h, groups)| CullShape {
            bounds: Bounds {
                min: Vec3::new(-3.0, -0.1, -3.0),
                max: Vec3::new(3.0, h, 3.0),
            },
            trunk: Bounds {
                min: Vec3::new(-0.3, -0.1, -0.3),
                max: Vec3::new(0.3, h * 0.8, 0.3),
            },
            groups: (0..groups)
                .map(|g| {
                    let a = g as f32 * 2.4;
                    BoundingSphere {
                        center: Vec3::new(2.0 * a.cos(), h * 0.7, 2.0 * a.sin()),
                        radius: 0.6,
                    }
                })
                .collect(),
        })
        .collect()
}

fn culling_forest(n: usize, size: f32) -> Vec<CullInstance> {
    let side = (n as f32).sqrt().ceil() as usize;
    let mut next = unit_noise();
    (0..n)
        .map(|i| {
            let (x, z) = ((i % side) as f32 + next(), (i / side) as f32 + next());
            CullInstance {
                transform: Affine3A::from_scale_rotation_translation(
                    Vec3::splat(0.8 + 0.4 * next()),
                    Quat::from_rotation_y(next() * 6.0),
                    Vec3::new(x / side as f32 * size, 0.0, z / side as f32 * size),
                ),
                shape: (i % 3) as u32,
            }
        })
        .collect()
}

/// The per-object searches of the Budget stage alone: each of `trees` trees' TCLOD trunk
/// and its leaves chosen as one, the trees of `models` in turn, 540 px high, 1.2 rad
/// vertical field of view, each object a few microseconds of rendering time. Two views:
/// `far` (1 000–1 050 units deep, every trunk below half a pixel) and `middle`
/// (400–450 units, about half the trunks lines of a pixel or two).
pub fn tree_searches(models: Vec<TreeModel>, trees: usize) -> Vec<Workload> {
    assert!(!models.is_empty(), "tree_searches needs a model");
    let models = std::sync::Arc::new(models);
    let costs = PrimitiveCosts::from_calibration(&Calibration::default(), 1.0)
        .within_viewport(540.0 * 540.0);
    let sizes = PixelRange::default();
    [("far", 1000.0), ("middle", 400.0)]
        .into_iter()
        .map(|(name, depth)| {
            let views = search_views(trees, depth, models.len());
            let (models, costs) = (models.clone(), costs.clone());
            let mut lists: Vec<TreeDrawList> =
                (0..trees).map(|_| TreeDrawList::default()).collect();
            Workload::new(name, 2 * trees as u64, move || {
                let mut total = 0.0;
                for ((model, view, depth, trunk_time, leaf_time), list) in
                    views.iter().zip(&mut lists)
                {
                    let model = &models[*model];
                    total +=
                        select::trunk_tclod(model, view, &costs, sizes, *trunk_time, list).cost;
                    let leaves = LeafMethod::Tclod(sizes);
                    total += select::leaves_at_depth(
                        model, view, &costs, leaves, *depth, *leaf_time, list,
                    )
                    .cost;
                }
                black_box(total);
            })
        })
        .collect()
}

/// Per tree: its model, view, leaves' depth and the times its trunk and leaves get.
fn search_views(trees: usize, depth: f32, models: usize) -> Vec<(usize, TreeView, f32, f32, f32)> {
    let projection = Projection::perspective(1.2, 540.0);
    let mut next = unit_noise();
    (0..trees)
        .map(|i| {
            let depth = depth + 50.0 * next();
            let view = TreeView {
                scale: 0.8 + 0.4 * next(),
                trunk_depth: depth,
                projection,
            };
            (i % models, view, depth, 4.0e-6 * next(), 4.0e-6 * next())
        })
        .collect()
}

/// The wind's per-instance work for one tree of `model` under spring-set association
/// `rules`, three springs moving: its ring offsets with every movement applied
/// (`ring_offsets`), with sub-centimetre movements accumulated instead
/// (`ring_offsets_thresholded`, the stage's half-pixel threshold at about 50 m), and its
/// moved culling bounds (`moved_bounds`).
pub fn wind_per_tree(model: &TreeModel, rules: &[AssociationRule]) -> Vec<Workload> {
    let springs = [
        Vec3::new(0.08, 0.0, 0.03),
        Vec3::new(0.06, 0.0, 0.01),
        Vec3::new(0.04, 0.0, 0.02),
    ];
    let rig = std::sync::Arc::new(WindRig::new(model, &associate(model, rules, springs.len())));
    let rings = model.rings.len() as u64;
    let mut workloads: Vec<Workload> = [("ring_offsets", 0.0), ("ring_offsets_thresholded", 0.01)]
        .into_iter()
        .map(|(name, threshold)| {
            let rig = rig.clone();
            let mut offsets = Vec::new();
            Workload::new(name, rings, move || {
                let rotation = Quat::from_rotation_y(0.3);
                ring_offsets(
                    &rig,
                    black_box(&springs),
                    rotation,
                    1.1,
                    threshold,
                    &mut offsets,
                );
            })
        })
        .collect();
    let mut offsets = Vec::new();
    ring_offsets(
        &rig,
        &springs,
        Quat::from_rotation_y(0.3),
        1.1,
        0.0,
        &mut offsets,
    );
    let mut shape = CullShape::from(model);
    workloads.push(Workload::new("moved_bounds", rings, move || {
        moved_bounds(&rig, black_box(&offsets), &mut shape);
    }));
    workloads
}
