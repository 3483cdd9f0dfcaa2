//! The ring offsets the render pass applies, held only for the instances that move: a
//! forest's far trees (below the motion level of detail, or out of view) cost an empty
//! span each, not a block of zeros per ring. Far trees that sway alike share a block
//! ([`share`](RingOffsetTable::share)).

use std::collections::HashMap;

use bevy::math::Vec3A;
use bevy::prelude::*;

/// Ring offsets of the moving instances, indexed like
/// [`ForestInstances`](crate::instance::ForestInstances): [`get`](Self::get)`(i)` is
/// instance `i`'s offsets in its model's ring order (model space), or `None` while it is
/// at rest. The memory held follows the most instances that moved at once, not the
/// forest's size.
#[derive(Resource, Clone, Debug, Default)]
pub(crate) struct RingOffsetTable {
    /// Per instance, its block in `offsets`; `len` 0 at rest.
    spans: Vec<Span>,
    offsets: Vec<Vec3A>,
    /// Starts of blocks given back by instances that came to rest, by block length.
    free: HashMap<u32, Vec<u32>>,
    moving: u32,
}

/// Where one instance's offsets are.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Span {
    start: u32,
    /// 0 at rest.
    len: u32,
    /// The block is a shared one ([`RingOffsetTable::new_shared_block`]), not the
    /// instance's own: coming to rest does not free it.
    shared: bool,
}

impl RingOffsetTable {
    /// A table of `instances` instances, every one at rest.
    #[cfg(test)]
    pub(crate) fn at_rest(instances: usize) -> Self {
        let mut table = Self::default();
        table.reset(instances);
        table
    }

    /// Puts every instance at rest and sizes the table for `instances` instances.
    pub(crate) fn reset(&mut self, instances: usize) {
        self.spans.clear();
        self.spans.resize(instances, Span::default());
        self.offsets.clear();
        self.free.clear();
        self.moving = 0;
    }

    /// Instances in the table, moving or not.
    #[cfg(test)]
    pub(crate) fn len(&self) -> usize {
        self.spans.len()
    }

    /// Instances with offsets.
    #[cfg(any(test, feature = "render"))]
    pub(crate) fn moving(&self) -> u32 {
        self.moving
    }

    /// Instance `instance`'s ring offsets, or `None` while it is at rest (or past the
    /// table).
    #[cfg(test)]
    pub(crate) fn get(&self, instance: usize) -> Option<&[Vec3A]> {
        let Span { start, len, .. } = *self.spans.get(instance)?;
        (len > 0).then(|| &self.offsets[start as usize..(start + len) as usize])
    }

    /// Where instance `instance`'s offsets start in [`all_offsets`](Self::all_offsets),
    /// when it is moving with one offset for each of `rings` rings.
    #[cfg(any(test, feature = "render"))]
    pub(crate) fn block(&self, instance: usize, rings: u32) -> Option<u32> {
        let Span { start, len, .. } = *self.spans.get(instance)?;
        (len > 0 && len == rings).then_some(start)
    }

    /// Every block of offsets, the moving instances' and the free ones: what the render
    /// pass uploads whole, each moving instance reading its block from
    /// [`block`](Self::block) on.
    #[cfg(any(test, feature = "render"))]
    pub(crate) fn all_offsets(&self) -> &[Vec3A] {
        &self.offsets
    }

    /// Gives `instance` the offsets `rings` (one per ring of its model); an empty slice
    /// puts it at rest. An instance past the table is left out: the table is sized by
    /// [`reset`](Self::reset).
    pub(crate) fn set(&mut self, instance: usize, rings: &[Vec3A]) {
        let Some(&span) = self.spans.get(instance) else {
            return;
        };
        if span.shared || span.len as usize != rings.len() {
            self.rest(instance);
            if rings.is_empty() {
                return;
            }
            let len = rings.len() as u32;
            let start = self.allocate(len);
            self.spans[instance] = Span {
                start,
                len,
                shared: false,
            };
            self.moving += 1;
        }
        self.write_block(self.spans[instance].start, rings);
    }

    /// A block of `len` offsets: a free one of that length, or a new one at the end.
    fn allocate(&mut self, len: u32) -> u32 {
        match self.free.get_mut(&len).and_then(Vec::pop) {
            Some(start) => start,
            None => {
                let start = self.offsets.len() as u32;
                self.offsets
                    .resize(self.offsets.len() + len as usize, Vec3A::ZERO);
                start
            }
        }
    }

    /// A block of `len` offsets that no instance owns, for instances to
    /// [`share`](Self::share); where it starts. It is kept until
    /// [`release_shared_block`](Self::release_shared_block) or [`reset`](Self::reset).
    pub(crate) fn new_shared_block(&mut self, len: u32) -> u32 {
        self.allocate(len)
    }

    /// Writes `offsets` into the block starting at `start` (a shared block's, from
    /// [`new_shared_block`](Self::new_shared_block)).
    pub(crate) fn write_block(&mut self, start: u32, offsets: &[Vec3A]) {
        let start = start as usize;
        if let Some(block) = self.offsets.get_mut(start..start + offsets.len()) {
            block.copy_from_slice(offsets);
        }
    }

    /// Points `instance` at the shared block of `len` offsets at `start` instead of a
    /// block of its own (which is freed).
    pub(crate) fn share(&mut self, instance: usize, start: u32, len: u32) {
        let Some(&span) = self.spans.get(instance) else {
            return;
        };
        if span.shared && span.start == start && span.len == len {
            return;
        }
        self.rest(instance);
        if len == 0 {
            return;
        }
        self.spans[instance] = Span {
            start,
            len,
            shared: true,
        };
        self.moving += 1;
    }

    /// Frees a shared block (no instance may point at it any longer).
    pub(crate) fn release_shared_block(&mut self, start: u32, len: u32) {
        if len > 0 {
            self.free.entry(len).or_default().push(start);
        }
    }

    /// Whether `instance` points at a shared block.
    pub(crate) fn is_shared(&self, instance: usize) -> bool {
        self.spans.get(instance).is_some_and(|s| s.shared)
    }

    /// Puts `instance` back at rest; its block is kept for the next instance of the same
    /// ring count to move.
    pub(crate) fn rest(&mut self, instance: usize) {
        let Some(span) = self.spans.get_mut(instance) else {
            return;
        };
        let Span { start, len, shared } = *span;
        if len == 0 {
            return;
        }
        *span = Span::default();
        if !shared {
            self.free.entry(len).or_default().push(start);
        }
        self.moving -= 1;
    }

    /// Takes `instance` out as `Vec::swap_remove` does: the last instance (and its
    /// offsets) takes its index.
    pub(crate) fn swap_remove(&mut self, instance: usize) {
        if instance < self.spans.len() {
            self.rest(instance);
            self.spans.swap_remove(instance);
        }
    }

    /// Adds an instance at rest at the end.
    pub(crate) fn push(&mut self) {
        self.spans.push(Span::default());
    }

    /// Ring offsets held, moving instances', shared and free blocks together: the table's
    /// memory is this times 16 bytes (plus 12 per instance).
    pub(crate) fn rings_held(&self) -> usize {
        self.offsets.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_moving_instance_reads_back_its_offsets_and_none_at_rest() {
        let mut table = RingOffsetTable::at_rest(3);
        assert_eq!(table.get(1), None);
        table.set(1, &[Vec3A::X, Vec3A::Y]);
        table.set(2, &[Vec3A::Z]);
        assert_eq!(table.get(1), Some(&[Vec3A::X, Vec3A::Y][..]));
        assert_eq!(table.get(2), Some(&[Vec3A::Z][..]));
        assert_eq!(table.get(0), None);
        assert_eq!(table.moving(), 2);
        table.rest(1);
        assert_eq!(table.get(1), None);
        assert_eq!(table.get(2), Some(&[Vec3A::Z][..]));
        assert_eq!(table.moving(), 1);
        table.set(2, &[]);
        assert_eq!((table.get(2), table.moving()), (None, 0));
        // Past the table: left out, not a panic.
        table.set(7, &[Vec3A::X]);
        assert_eq!((table.get(7), table.moving()), (None, 0));
    }

    #[test]
    fn memory_follows_the_instances_moving_at_once_not_the_forest() {
        let mut table = RingOffsetTable::at_rest(10_000);
        let rings = [Vec3A::ONE; 40];
        // A hundred trees move at a time, the crowd walking through the whole forest.
        for step in 0..100 {
            let first = step * 100;
            if step > 0 {
                (first - 100..first).for_each(|i| table.rest(i));
            }
            (first..first + 100).for_each(|i| table.set(i, &rings));
        }
        assert_eq!(table.moving(), 100);
        assert_eq!(table.rings_held(), 100 * rings.len());
        // A second model's ring count takes its own blocks; the first's are kept free.
        table.set(0, &[Vec3A::X; 7]);
        assert_eq!(table.rings_held(), 100 * rings.len() + 7);
        assert_eq!(table.get(9_950), Some(&rings[..]));
    }

    #[test]
    fn each_moving_instance_s_block_starts_where_its_offsets_are() {
        let mut table = RingOffsetTable::at_rest(4);
        table.set(2, &[Vec3A::X; 3]);
        table.set(0, &[Vec3A::Y, Vec3A::Z]);
        table.set(3, &[Vec3A::ONE; 3]);
        table.rest(2);
        for (instance, rings) in [(0, 2), (3, 3)] {
            let start = table.block(instance, rings).expect("moving") as usize;
            assert_eq!(
                &table.all_offsets()[start..start + rings as usize],
                table.get(instance).unwrap()
            );
        }
        // At rest, past the table, or a ring count that is not the block's: none.
        assert_eq!(table.block(1, 2), None);
        assert_eq!(table.block(2, 3), None);
        assert_eq!(table.block(9, 3), None);
        assert_eq!(table.block(0, 3), None);
    }

    #[test]
    fn instances_sharing_a_block_read_it_and_coming_to_rest_does_not_free_it() {
        let mut table = RingOffsetTable::at_rest(3);
        table.set(0, &[Vec3A::X; 2]);
        let shared = table.new_shared_block(2);
        table.write_block(shared, &[Vec3A::Y, Vec3A::Z]);
        // Instance 0 gives its own block back; 1 and 2 join it at rest.
        for i in 0..3 {
            table.share(i, shared, 2);
        }
        assert_eq!(table.moving(), 3);
        for i in 0..3 {
            assert!(table.is_shared(i));
            assert_eq!(table.get(i), Some(&[Vec3A::Y, Vec3A::Z][..]));
            assert_eq!(table.block(i, 2), Some(shared));
        }
        table.rest(1);
        assert_eq!((table.get(1), table.moving()), (None, 2));
        // The freed own block is reused by the next instance that moves alone; the shared
        // one is not.
        table.set(1, &[Vec3A::ONE; 2]);
        assert_ne!(table.block(1, 2), Some(shared));
        assert_eq!(table.get(0), Some(&[Vec3A::Y, Vec3A::Z][..]));
        assert_eq!(table.rings_held(), 4);
        // Leaving the shared block for an own one, and the block released.
        table.set(2, &[Vec3A::NEG_X; 2]);
        assert!(!table.is_shared(2));
        table.rest(0);
        table.release_shared_block(shared, 2);
        table.set(0, &[Vec3A::NEG_Y; 2]);
        assert_eq!(table.block(0, 2), Some(shared));
        assert_eq!(table.get(2), Some(&[Vec3A::NEG_X; 2][..]));
        assert_eq!(table.rings_held(), 6);
    }

    #[test]
    fn a_reused_block_holds_only_its_new_instances_offsets() {
        let mut table = RingOffsetTable::at_rest(2);
        table.set(0, &[Vec3A::X, Vec3A::X]);
        table.rest(0);
        table.set(1, &[Vec3A::Y, Vec3A::Z]);
        assert_eq!(table.get(1), Some(&[Vec3A::Y, Vec3A::Z][..]));
        assert_eq!(table.get(0), None);
        assert_eq!(table.rings_held(), 2);
    }
}
