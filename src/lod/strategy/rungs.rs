//! The strategies that see each object as rungs of representations at
//! [`RUNG_FRACTIONS`](crate::lod::RUNG_FRACTIONS) of its full cost
//! ([`FunkhouserSequin`](crate::budget::FunkhouserSequin), its incremental variant and
//! the [`TriangleBudget`](crate::budget::TriangleBudget)): the rungs priced by each
//! object's search, the solver's choice drawn.

use bevy::platform::collections::HashMap;
use bevy::prelude::*;

use super::{HandOut, Outcome, Strategy};
use crate::budget::{BudgetProblem, BudgetStrategy, Level, ObjectDesc, PreviousSelection};
use crate::lod::RUNG_FRACTIONS;
use crate::lod::value::Part;

/// A rung solver's state, kept between frames.
#[derive(Default)]
pub(super) struct RungGreedy<S> {
    solver: S,
    problem: BudgetProblem,
    /// Per object, the time each rung's search is given.
    rung_times: Vec<[f32; RUNG_FRACTIONS.len()]>,
    /// Last frame's rung per (entity, part), for the incremental solvers.
    previous: HashMap<(Entity, Part), u32>,
    next_previous: HashMap<(Entity, Part), u32>,
}

impl<S: BudgetStrategy + Default> Strategy for RungGreedy<S> {
    fn hand_out(&mut self, hand_out: &mut HandOut) -> Outcome {
        let search = hand_out.search;
        self.problem.clear();
        self.rung_times.clear();
        self.next_previous.clear();
        for (i, &object) in search.objects.iter().enumerate() {
            let value = hand_out.values[i];
            let (rungs, times) = search.rungs(i, value, hand_out.scratch);
            let previous = self
                .previous
                .get(&(search.entity(object), object.part))
                .map_or(PreviousSelection::New, |&l| PreviousSelection::Level(l));
            let desc = ObjectDesc {
                value,
                complexity: hand_out.complexities[i],
                previous,
            };
            if self.problem.push_object(desc, &rungs).is_err() {
                // Not expected: values and costs are finite by construction. Keep the
                // indices aligned with a free, worthless object.
                let _ = self
                    .problem
                    .push_object(ObjectDesc::default(), &[Level::new(0.0, 0.0)]);
            }
            self.rung_times.push(times);
        }
        let stats = self
            .solver
            .distribute(&self.problem, hand_out.rendering, hand_out.allocations);
        let mut outcome = Outcome::of(stats);
        for (i, allocation) in hand_out.allocations.iter().enumerate() {
            if let Some(level) = allocation.level {
                let time = self.rung_times[i][level as usize];
                outcome.count(hand_out.choices.draw(search, i, time).0);
                let object = search.objects[i];
                self.next_previous
                    .insert((search.entity(object), object.part), level);
            }
        }
        core::mem::swap(&mut self.previous, &mut self.next_previous);
        outcome
    }
}
