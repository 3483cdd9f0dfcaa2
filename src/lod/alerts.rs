//! One-shot alerts from the Budget stage, as Bevy events an app observes
//! (`app.add_observer(|alert: On<TargetUnreachable>| …)`): raised once when a condition
//! has lasted three seconds (`TARGET_WARNING_SECS`), and again only after it has cleared;
//! never once a frame.

use bevy::prelude::*;

use super::{LodDiagnostics, TARGET_WARNING_SECS};

/// Why the target frame time cannot be held.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Reflect)]
pub enum Unreachable {
    /// The target is at or below the logic time: nothing is left to render with, and
    /// every object is drawn at its cheapest.
    BelowLogic,
    /// The cheapest representations of what is in view alone take longer than the
    /// rendering time: nothing visible is dropped, so the frame runs over.
    TooMuchInView,
}

/// The target frame time cannot be held, and has not been for three seconds
/// (`TARGET_WARNING_SECS`; a warning is logged as well). Raised once; again only after the target has
/// been held in between.
#[derive(Event, Clone, Debug, PartialEq, Reflect)]
pub struct TargetUnreachable {
    /// Why.
    pub cause: Unreachable,
    /// The target, milliseconds.
    pub target_ms: f32,
    /// The logic time predicted for the frame, milliseconds.
    pub logic_ms: f32,
    /// What the cheapest representations of everything in view cost, milliseconds.
    pub floor_ms: f32,
    /// The rendering time left for them, milliseconds.
    pub rendering_ms: f32,
    /// Objects in view.
    pub visible_objects: u32,
}

/// Watches a frame's diagnostics for a target that cannot be held.
#[derive(Default)]
pub(super) struct TargetWatch {
    since: Option<f32>,
    raised: bool,
}

impl TargetWatch {
    /// The alert to raise after a frame with `diagnostics` at `now` seconds, if any.
    pub(super) fn observe(
        &mut self,
        diagnostics: &LodDiagnostics,
        now: f32,
    ) -> Option<TargetUnreachable> {
        let cause = if diagnostics.target_below_logic {
            Unreachable::BelowLogic
        } else if diagnostics.floor_excess_ms > 0.0 {
            Unreachable::TooMuchInView
        } else {
            *self = Self::default();
            return None;
        };
        let since = *self.since.get_or_insert(now);
        if self.raised || now - since < TARGET_WARNING_SECS {
            return None;
        }
        self.raised = true;
        Some(TargetUnreachable {
            cause,
            target_ms: diagnostics.target_ms,
            logic_ms: diagnostics.logic_ms,
            floor_ms: diagnostics.floor_ms,
            rendering_ms: diagnostics.render_budget_ms,
            visible_objects: diagnostics.visible_objects,
        })
    }
}

/// Logs `alert` (once, as it is raised) and triggers it for the app's observers.
pub(super) fn raise(commands: &mut Commands, alert: TargetUnreachable) {
    match alert.cause {
        Unreachable::BelowLogic => warn!(
            "FrameBudget: target {:.1} ms has been at or below the logic time ({:.1} ms) for {TARGET_WARNING_SECS} s; every object is drawn at its cheapest",
            alert.target_ms, alert.logic_ms
        ),
        Unreachable::TooMuchInView => warn!(
            "FrameBudget: target {:.1} ms cannot be held with {} objects in view: their cheapest representations take {:.1} ms of the {:.1} ms left to render, for {TARGET_WARNING_SECS} s",
            alert.target_ms, alert.visible_objects, alert.floor_ms, alert.rendering_ms
        ),
    }
    commands.trigger(alert);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(below_logic: bool, floor_excess_ms: f32) -> LodDiagnostics {
        LodDiagnostics {
            target_below_logic: below_logic,
            floor_excess_ms,
            ..Default::default()
        }
    }

    #[test]
    fn an_alert_is_raised_once_after_the_delay_and_again_only_after_it_cleared() {
        let mut watch = TargetWatch::default();
        let over = frame(false, 2.0);
        assert!(watch.observe(&over, 0.0).is_none());
        assert!(watch.observe(&over, TARGET_WARNING_SECS * 0.5).is_none());
        let alert = watch.observe(&over, TARGET_WARNING_SECS).unwrap();
        assert_eq!(alert.cause, Unreachable::TooMuchInView);
        assert!(watch.observe(&over, TARGET_WARNING_SECS * 2.0).is_none());
        // Held for a frame: the next lasting failure is raised again.
        assert!(watch.observe(&frame(false, 0.0), 10.0).is_none());
        assert!(watch.observe(&frame(true, 0.0), 11.0).is_none());
        let alert = watch
            .observe(&frame(true, 0.0), 11.0 + TARGET_WARNING_SECS)
            .unwrap();
        assert_eq!(alert.cause, Unreachable::BelowLogic);
    }
}
