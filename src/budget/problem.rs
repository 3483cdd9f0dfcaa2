//! The shared vocabulary of every budget strategy: one frame's objects and their
//! representations ([`BudgetProblem`]), what a strategy hands back per object
//! ([`Allocation`]) and per frame ([`BudgetStats`]), and the [`BudgetStrategy`] trait.

use bevy::reflect::Reflect;
use serde::{Deserialize, Serialize};

/// One representation of an object: what it costs to draw and what it is worth.
///
/// Ladders are ordered **best → cheapest**: index 0 is the most detailed
/// representation, the last index the cheapest. Costs must not increase along the
/// ladder. Robin Hood only reads the costs; Funkhouser–Séquin, the oracle and the
/// hierarchical strategy also read the benefits.
#[derive(Clone, Copy, Debug, PartialEq, Default, Serialize, Deserialize, Reflect)]
pub(crate) struct Level {
    /// Predicted rendering time of this representation, in seconds.
    pub cost: f32,
    /// Perceptual benefit of this representation (Funkhouser–Séquin's `Benefit`).
    pub benefit: f32,
}

impl Level {
    /// A representation costing `cost` seconds with benefit `benefit`.
    pub(crate) const fn new(cost: f32, benefit: f32) -> Self {
        Self { cost, benefit }
    }

    /// Funkhouser–Séquin's `Value`: benefit per second. A free representation with
    /// a positive benefit is infinitely valuable; a free one without benefit is worth 0.
    pub(crate) fn value(&self) -> f32 {
        if self.cost > 0.0 {
            self.benefit / self.cost
        } else if self.benefit > 0.0 {
            f32::INFINITY
        } else {
            0.0
        }
    }
}

/// What an object drew last frame, for the strategies that start from it
/// (Funkhouser–Séquin incremental, the triangle budget, the hierarchical strategy).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize, Reflect)]
pub(crate) enum PreviousSelection {
    /// Not visible last frame (or the caller does not track it): start at the cheapest level.
    #[default]
    New,
    /// Visible but not drawn last frame.
    Dropped,
    /// Drawn at this ladder index last frame.
    Level(u32),
}

/// One frame's objects, in struct-of-arrays form so that a frame's worth of
/// objects lives in a handful of reusable allocations.
///
/// Fill it with [`BudgetProblem::push_object`], hand it to a [`BudgetStrategy`], and
/// [`clear`](BudgetProblem::clear) it for the next frame (the capacity is kept).
#[derive(Clone, Debug, Default)]
pub(crate) struct BudgetProblem {
    values: Vec<f32>,
    complexities: Vec<f32>,
    previous: Vec<PreviousSelection>,
    ladder_offsets: Vec<u32>,
    levels: Vec<Level>,
}

/// The per-object scalars of [`BudgetProblem::push_object`].
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub(crate) struct ObjectDesc {
    /// The object's value `v_i` this frame (see [`ValueFunction`](super::ValueFunction)).
    /// Must be finite and non-negative.
    pub value: f32,
    /// The sort key of the object's *type*: the cost of its best representation at a
    /// reference projected area (paper §5.1). Robin Hood visits objects in ascending
    /// complexity, simple → complex.
    pub complexity: f32,
    /// What the object drew last frame.
    pub previous: PreviousSelection,
}

/// Why an object was refused by [`BudgetProblem::push_object`].
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub(crate) enum BudgetInputError {
    /// The object has no representation at all.
    #[error("object {object} has no representations: every object needs at least one level")]
    EmptyLadder {
        /// Index the object would have had.
        object: usize,
    },
    /// The value is NaN, infinite or negative.
    #[error("object {object} has value {value}: values must be finite and non-negative")]
    InvalidValue {
        /// Index the object would have had.
        object: usize,
        /// The offending value.
        value: f32,
    },
    /// The complexity is NaN or infinite.
    #[error("object {object} has complexity {complexity}: complexities must be finite")]
    InvalidComplexity {
        /// Index the object would have had.
        object: usize,
        /// The offending complexity.
        complexity: f32,
    },
    /// A cost or benefit is NaN, infinite or negative.
    #[error(
        "object {object}, level {level}: cost {cost} and benefit {benefit} must be finite and non-negative"
    )]
    InvalidLevel {
        /// Index the object would have had.
        object: usize,
        /// Ladder index of the offending level.
        level: usize,
        /// Its cost.
        cost: f32,
        /// Its benefit.
        benefit: f32,
    },
    /// The ladder is not ordered best → cheapest.
    #[error(
        "object {object}, level {level}: cost {cost} exceeds the previous level's {previous_cost}; ladders run best (most expensive) → cheapest"
    )]
    CostsIncreasing {
        /// Index the object would have had.
        object: usize,
        /// Ladder index of the offending level.
        level: usize,
        /// Its cost.
        cost: f32,
        /// The cost of the level before it.
        previous_cost: f32,
    },
    /// The previous selection names a level the ladder does not have.
    #[error("object {object}: previous level {level} is outside its ladder of {len} levels")]
    PreviousOutOfRange {
        /// Index the object would have had.
        object: usize,
        /// The previous level given.
        level: u32,
        /// The ladder's length.
        len: usize,
    },
    /// More objects or levels than 32-bit indices can address.
    #[error("too many objects or levels for one problem (at most u32::MAX)")]
    TooLarge,
}

impl BudgetProblem {
    /// An empty problem.
    #[cfg(test)]
    pub(crate) fn new() -> Self {
        Self::default()
    }

    /// An empty problem with room for `objects` objects of about `levels_per_object` levels.
    #[cfg(any(test, feature = "testing"))]
    pub(crate) fn with_capacity(objects: usize, levels_per_object: usize) -> Self {
        let mut ladder_offsets = Vec::with_capacity(objects + 1);
        ladder_offsets.push(0);
        Self {
            values: Vec::with_capacity(objects),
            complexities: Vec::with_capacity(objects),
            previous: Vec::with_capacity(objects),
            ladder_offsets,
            levels: Vec::with_capacity(objects * levels_per_object),
        }
    }

    /// Removes every object, keeping the allocations.
    pub(crate) fn clear(&mut self) {
        self.values.clear();
        self.complexities.clear();
        self.previous.clear();
        self.ladder_offsets.clear();
        self.levels.clear();
    }

    /// Adds one object with its ladder of representations (best → cheapest) and
    /// returns its index. Nothing is added when the input is refused.
    pub(crate) fn push_object(
        &mut self,
        desc: ObjectDesc,
        ladder: &[Level],
    ) -> Result<usize, BudgetInputError> {
        let object = self.values.len();
        if ladder.is_empty() {
            return Err(BudgetInputError::EmptyLadder { object });
        }
        if !desc.value.is_finite() || desc.value < 0.0 {
            return Err(BudgetInputError::InvalidValue {
                object,
                value: desc.value,
            });
        }
        if !desc.complexity.is_finite() {
            return Err(BudgetInputError::InvalidComplexity {
                object,
                complexity: desc.complexity,
            });
        }
        for (level, l) in ladder.iter().enumerate() {
            let finite = l.cost.is_finite() && l.benefit.is_finite();
            if !finite || l.cost < 0.0 || l.benefit < 0.0 {
                return Err(BudgetInputError::InvalidLevel {
                    object,
                    level,
                    cost: l.cost,
                    benefit: l.benefit,
                });
            }
            if level > 0 && l.cost > ladder[level - 1].cost {
                return Err(BudgetInputError::CostsIncreasing {
                    object,
                    level,
                    cost: l.cost,
                    previous_cost: ladder[level - 1].cost,
                });
            }
        }
        if let PreviousSelection::Level(level) = desc.previous
            && level as usize >= ladder.len()
        {
            return Err(BudgetInputError::PreviousOutOfRange {
                object,
                level,
                len: ladder.len(),
            });
        }
        let end = u32::try_from(self.levels.len() + ladder.len())
            .map_err(|_| BudgetInputError::TooLarge)?;
        if object >= u32::MAX as usize {
            return Err(BudgetInputError::TooLarge);
        }
        if self.ladder_offsets.is_empty() {
            self.ladder_offsets.push(0);
        }
        self.values.push(desc.value);
        self.complexities.push(desc.complexity);
        self.previous.push(desc.previous);
        self.levels.extend_from_slice(ladder);
        self.ladder_offsets.push(end);
        Ok(object)
    }

    /// Number of objects.
    pub(crate) fn len(&self) -> usize {
        self.values.len()
    }

    /// Every object's value, by object index.
    pub(crate) fn values(&self) -> &[f32] {
        &self.values
    }

    /// Every object's complexity key, by object index.
    pub(crate) fn complexities(&self) -> &[f32] {
        &self.complexities
    }

    /// What object `object` drew last frame.
    pub(crate) fn previous(&self, object: usize) -> PreviousSelection {
        self.previous[object]
    }

    /// The ladder of object `object`, best → cheapest.
    pub(crate) fn ladder(&self, object: usize) -> &[Level] {
        let start = self.ladder_offsets[object] as usize;
        let end = self.ladder_offsets[object + 1] as usize;
        &self.levels[start..end]
    }

    /// Object `object`'s levels as `(ladder index, cost, benefit)`, cheapest first
    /// (ascending cost).
    pub(crate) fn cheapest_first(
        &self,
        object: usize,
    ) -> impl Iterator<Item = (u32, f64, f64)> + '_ {
        self.ladder(object)
            .iter()
            .enumerate()
            .rev()
            .map(|(level, l)| (level as u32, f64::from(l.cost), f64::from(l.benefit)))
    }

    /// The total benefit of a selection (one ladder index or `None` per object).
    ///
    /// A truncated allocation counts the benefit of the level it names.
    #[cfg(test)]
    pub(crate) fn benefit_of(&self, allocations: &[Allocation]) -> f64 {
        allocations
            .iter()
            .enumerate()
            .filter_map(|(i, a)| {
                a.level
                    .map(|l| f64::from(self.ladder(i)[l as usize].benefit))
            })
            .sum()
    }
}

/// What a strategy decided for one object.
#[derive(Clone, Copy, Debug, PartialEq, Default, Serialize, Deserialize, Reflect)]
pub(crate) struct Allocation {
    /// Time handed to the object, in seconds. Strategies without a notion of
    /// allotment (Funkhouser–Séquin, the triangle budget, the hierarchical one)
    /// report the cost of what they selected.
    pub given: f32,
    /// Predicted time of what the object will draw, in seconds.
    pub used: f32,
    /// Ladder index of the chosen representation, `None` when the object is not drawn.
    pub level: Option<u32>,
    /// The object is drawn time-critically: even its cheapest representation did not
    /// fit its allotment, so it draws that representation truncated (or, for a
    /// discrete ladder, in full, overrunning its allotment by [`Allocation::overrun`]).
    pub truncated: bool,
}

impl Allocation {
    /// An object that draws nothing.
    pub(crate) const DROPPED: Self = Self {
        given: 0.0,
        used: 0.0,
        level: None,
        truncated: false,
    };

    /// An object drawing `level`, given exactly its cost: how strategies without a notion of
    /// allotment report what they selected.
    pub(crate) const fn drawn(cost: f32, level: u32) -> Self {
        Self {
            given: cost,
            used: cost,
            level: Some(level),
            truncated: false,
        }
    }

    /// Whether the object draws anything.
    pub(crate) fn is_drawn(&self) -> bool {
        self.level.is_some()
    }

    /// Time used beyond the allotment (only truncated objects have any).
    pub(crate) fn overrun(&self) -> f32 {
        (self.used - self.given).max(0.0)
    }
}

/// Per-frame totals every strategy reports, so strategies can be compared frame by frame.
#[derive(Clone, Copy, Debug, PartialEq, Default, Serialize, Deserialize, Reflect)]
pub(crate) struct BudgetStats {
    /// Rendering time the strategy was asked to distribute, in seconds (after clamping
    /// NaN or negative input to 0).
    pub rendering_time: f32,
    /// Sum of [`Allocation::given`].
    pub given: f32,
    /// Sum of [`Allocation::used`]: the predicted rendering cost of the selection.
    pub used: f32,
    /// Rendering time nobody used (the paper's remainder, or residue): the rendering
    /// time minus what objects used within their allotments. A truncated object's
    /// overrun does not use up time another object left over.
    pub wasted: f32,
    /// Predicted time beyond the rendering time (`used − rendering_time`, if positive),
    /// caused by truncated objects whose cheapest representation did not fit, or by
    /// strategies that cannot go lower.
    pub overrun: f32,
    /// Objects drawn (including truncated ones).
    pub drawn: u32,
    /// Visible objects not drawn at all.
    pub dropped: u32,
    /// Objects drawn time-critically (see [`Allocation::truncated`]).
    pub truncated: u32,
    /// The objects' cheapest representations together, when the strategy pays them
    /// before handing out the rest (Robin Hood); 0 otherwise.
    pub floor: f32,
    /// How far the cheapest representations alone exceed the rendering time
    /// (`floor − rendering_time`, if positive): the overrun no choice could avoid.
    pub floor_excess: f32,
}

impl BudgetStats {
    /// Totals over `allocations` for a frame with `rendering_time` seconds to render.
    pub(crate) fn from_allocations(rendering_time: f32, allocations: &[Allocation]) -> Self {
        let mut given = 0.0_f64;
        let mut used = 0.0_f64;
        let mut used_within_allotment = 0.0_f64;
        let mut stats = Self {
            rendering_time,
            ..Self::default()
        };
        for a in allocations {
            given += f64::from(a.given);
            used += f64::from(a.used);
            used_within_allotment += f64::from(a.used - a.overrun());
            if a.is_drawn() {
                stats.drawn += 1;
            } else {
                stats.dropped += 1;
            }
            if a.truncated {
                stats.truncated += 1;
            }
        }
        // Totals of near-`f32::MAX` times saturate instead of overflowing to infinity.
        let saturate = |x: f64| x.clamp(0.0, f64::from(f32::MAX)) as f32;
        stats.given = saturate(given);
        stats.used = saturate(used);
        stats.overrun = saturate(used - f64::from(rendering_time));
        stats.wasted = saturate(f64::from(rendering_time) - used_within_allotment);
        stats
    }
}

/// A way of handing one frame's rendering time to its objects.
///
/// Every strategy takes the same [`BudgetProblem`] and returns one [`Allocation`] per
/// object (in object order) plus the same [`BudgetStats`], so strategies are
/// interchangeable and comparable frame by frame.
pub(crate) trait BudgetStrategy: Send + Sync + 'static {
    /// A short human-readable name, for logs and reports.
    #[cfg(test)]
    fn name(&self) -> &'static str;

    /// Distributes `rendering_time` seconds over `problem`'s objects, writing exactly
    /// `problem.len()` allocations into `allocations` (which is cleared first).
    ///
    /// A NaN or negative `rendering_time` is treated as 0.
    fn distribute(
        &mut self,
        problem: &BudgetProblem,
        rendering_time: f32,
        allocations: &mut Vec<Allocation>,
    ) -> BudgetStats;
}

/// Clamps a rendering time to a finite, non-negative number (NaN and negatives → 0).
pub(crate) fn sanitize_time(time: f32) -> f32 {
    if time.is_finite() {
        time.max(0.0)
    } else if time == f32::INFINITY {
        f32::MAX
    } else {
        0.0
    }
}
