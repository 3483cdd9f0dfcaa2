//! [`StrategyKind::RobinHood`](crate::lod::StrategyKind::RobinHood): every object's
//! cheapest representation paid first, the rest walked simple → complex by value, each
//! object's search inside the walk (a remainder is only known once it has chosen).

use super::{HandOut, Outcome, Strategy};
use crate::budget::{Fit, RobinHood};
use crate::lod::parallel;
use crate::lod::select::Selected;
use crate::lod::value::Part;

/// Robin Hood's state, kept between frames for its allocations.
#[derive(Default)]
pub(super) struct RobinHoodStrategy {
    robin_hood: RobinHood,
    /// Per object, the cost of its cheapest representation.
    floors: Vec<f32>,
}

impl Strategy for RobinHoodStrategy {
    fn hand_out(&mut self, hand_out: &mut HandOut) -> Outcome {
        let HandOut {
            search,
            choices: draw,
            values,
            complexities,
            rendering,
            allocations,
            tree_parts,
            ..
        } = hand_out;
        let objects = search.objects;
        // Every object's floor is its own: computed in parallel where there are cores.
        self.floors.resize(objects.len(), 0.0);
        parallel::fill_each(&mut self.floors, |i| search.floor(i));
        // Only each object's last choice (a residue pass offers more time and replaces
        // it) is drawn, priced and learned from: `draw.drawn` holds it.
        let stats = self.robin_hood.distribute_with(
            values,
            complexities,
            &self.floors,
            *rendering,
            |i, given| {
                let (chosen, mesh_level) = draw.draw(search, i, given);
                // A tree part's level: 0 at full detail, nothing more to buy.
                let level = mesh_level.unwrap_or(u32::from(!chosen.full));
                Fit {
                    used: chosen.cost,
                    level,
                    truncated: chosen.truncated,
                }
            },
            allocations,
        );
        let choices = &*draw.drawn;
        let mut outcome = Outcome::of(stats);
        for &chosen in choices {
            outcome.count(chosen);
        }
        if let Some(parts) = tree_parts.as_deref_mut() {
            parts.clear();
            parts.resize(search.trees.len(), Selected::default());
            for (object, &chosen) in objects.iter().zip(choices.iter()) {
                if object.part != Part::Mesh {
                    let tree = &mut parts[object.index as usize];
                    *tree = Selected::both(*tree, chosen);
                }
            }
        }
        outcome
    }
}
