//! [`LodMode::Static`](crate::lod::LodMode::Static) and
//! [`LodMode::Unlimited`](crate::lod::LodMode::Unlimited): no time is handed out, every
//! object draws what its mode's method draws with all the time there is.

use super::{HandOut, Outcome};
use crate::budget::BudgetStats;
use crate::lod::search::FULL_DETAIL_TIME;

/// Every object drawn by its mode's method, whatever it costs.
pub(in crate::lod) fn draw_everything(hand_out: &mut HandOut) -> Outcome {
    let search = hand_out.search;
    let mut outcome = Outcome::default();
    for i in 0..search.objects.len() {
        outcome.count(hand_out.choices.draw(search, i, FULL_DETAIL_TIME).0);
    }
    outcome.stats = BudgetStats {
        rendering_time: hand_out.rendering,
        given: outcome.drawn.cost,
        used: outcome.drawn.cost,
        drawn: search.objects.len() as u32,
        ..BudgetStats::default()
    };
    outcome
}
