//! Lazy-deletion priority queues keyed by `f32`, shared by the incremental strategies.

use core::cmp::{Ordering, Reverse};
use std::collections::BinaryHeap;

#[derive(Clone, Copy, Debug)]
struct Entry {
    key: f32,
    item: u32,
    version: u32,
}

impl PartialEq for Entry {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}
impl Eq for Entry {}
impl PartialOrd for Entry {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Entry {
    fn cmp(&self, other: &Self) -> Ordering {
        // Ties are broken by item index, so results do not depend on heap internals.
        self.key
            .total_cmp(&other.key)
            .then_with(|| other.item.cmp(&self.item))
    }
}

/// Max- and min-queues over items whose keys change: every change bumps the item's
/// version, and entries with an old version are skipped when popped.
#[derive(Clone, Debug, Default)]
pub(crate) struct ItemQueues {
    versions: Vec<u32>,
    max: BinaryHeap<Entry>,
    min: BinaryHeap<Reverse<Entry>>,
}

impl ItemQueues {
    pub(crate) fn reset(&mut self, items: usize) {
        self.versions.clear();
        self.versions.resize(items, 0);
        self.max.clear();
        self.min.clear();
    }

    /// Invalidates every queued entry of `item`.
    pub(crate) fn touch(&mut self, item: usize) {
        self.versions[item] = self.versions[item].wrapping_add(1);
    }

    pub(crate) fn push_max(&mut self, item: usize, key: f32) {
        let version = self.versions[item];
        self.max.push(Entry {
            key,
            item: item as u32,
            version,
        });
    }

    pub(crate) fn push_min(&mut self, item: usize, key: f32) {
        let version = self.versions[item];
        self.min.push(Reverse(Entry {
            key,
            item: item as u32,
            version,
        }));
    }

    /// Queues many `(item, key)` max-entries at once (heapified in O(n)).
    pub(crate) fn extend_max(&mut self, entries: impl Iterator<Item = (usize, f32)>) {
        let versions = &self.versions;
        self.max.extend(entries.map(|(item, key)| Entry {
            key,
            item: item as u32,
            version: versions[item],
        }));
    }

    /// Queues many `(item, key)` min-entries at once (heapified in O(n)).
    pub(crate) fn extend_min(&mut self, entries: impl Iterator<Item = (usize, f32)>) {
        let versions = &self.versions;
        self.min.extend(entries.map(|(item, key)| {
            Reverse(Entry {
                key,
                item: item as u32,
                version: versions[item],
            })
        }));
    }

    /// The current item with the largest max-key.
    pub(crate) fn pop_max(&mut self) -> Option<usize> {
        while let Some(e) = self.max.pop() {
            if e.version == self.versions[e.item as usize] {
                return Some(e.item as usize);
            }
        }
        None
    }

    /// The current item with the smallest min-key.
    pub(crate) fn pop_min(&mut self) -> Option<usize> {
        while let Some(Reverse(e)) = self.min.pop() {
            if e.version == self.versions[e.item as usize] {
                return Some(e.item as usize);
            }
        }
        None
    }
}
