//! The `DrawLists` stage: the lists the Budget stage chose, written into the instances'
//! and group impostors' [`TreeDrawList`] components.

use std::time::Instant;

use bevy::prelude::*;

use super::LodDiagnostics;
use super::value::VisibleObjects;
use crate::draw::TreeDrawList;
use crate::instance::ForestInstances;

/// The lists the Budget stage chose this frame, and which components were written last
/// frame (to clear those not chosen again).
#[derive(Resource, Default)]
pub(super) struct ChosenLists {
    /// Per visible tree ([`VisibleObjects::trees`]), its list.
    pub(super) trees: Vec<TreeDrawList>,
    /// The group impostors drawn and their lists.
    pub(super) impostors: ImpostorLists,
    /// The group impostors whose lists were written last frame.
    impostors_shown: Vec<Entity>,
    /// The trees whose lists were written non-empty last frame.
    trees_shown: Vec<Entity>,
    /// Per instance, the frame stamp it was last chosen at (`stamp`: this frame's).
    stamps: Vec<u32>,
    stamp: u32,
}

/// The group impostors drawn this frame and their lists; the lists of earlier frames are
/// kept for their allocations.
#[derive(Default)]
pub(super) struct ImpostorLists {
    lists: Vec<(Entity, TreeDrawList)>,
    /// How many of `lists` are this frame's.
    drawn: usize,
}

impl ImpostorLists {
    /// An empty list for group impostor `entity`, drawn this frame.
    pub(super) fn push(&mut self, entity: Entity) -> &mut TreeDrawList {
        if self.drawn == self.lists.len() {
            self.lists.push((entity, TreeDrawList::default()));
        }
        let (slot, list) = &mut self.lists[self.drawn];
        *slot = entity;
        list.clear();
        self.drawn += 1;
        list
    }

    fn drawn_mut(&mut self) -> &mut [(Entity, TreeDrawList)] {
        &mut self.lists[..self.drawn]
    }
}

impl ChosenLists {
    /// A fresh, empty list for each of `trees` visible trees, and no group impostor.
    pub(super) fn clear_for(&mut self, trees: usize) {
        self.impostors.drawn = 0;
        self.trees.resize_with(trees, TreeDrawList::default);
        for list in &mut self.trees[..trees] {
            list.clear();
        }
    }
}

pub(super) fn write_draw_lists(
    mut chosen: ResMut<ChosenLists>,
    visible: Res<VisibleObjects>,
    table: Res<ForestInstances>,
    mut lists: Query<&mut TreeDrawList>,
    mut diagnostics: ResMut<LodDiagnostics>,
) {
    let start = Instant::now();
    // A kept selection's lists are the ones written (`trees` holds older ones, swapped
    // out): they stay as they are.
    if diagnostics.selection_kept {
        diagnostics.draw_lists_stage_ms = start.elapsed().as_secs_f32() * 1000.0;
        return;
    }
    let chosen = &mut *chosen;
    // Trees shown last frame and not chosen now draw nothing; the chosen ones get their
    // list. (Only those: the rest of a large forest is left alone, already empty.)
    chosen.stamp = chosen.stamp.wrapping_add(1).max(1);
    let stamp = chosen.stamp;
    chosen.stamps.resize(table.len(), 0);
    let held = visible.held.iter().copied();
    for instance in visible.trees.iter().map(|t| t.instance).chain(held) {
        if let Some(s) = chosen.stamps.get_mut(instance as usize) {
            *s = stamp;
        }
    }
    for entity in chosen.trees_shown.drain(..) {
        let again = table
            .index_of(entity)
            .is_some_and(|i| chosen.stamps.get(i as usize) == Some(&stamp));
        if !again && let Ok(mut list) = lists.get_mut(entity) {
            list.clear();
        }
    }
    for (tree, list_chosen) in visible.trees.iter().zip(&mut chosen.trees) {
        let Ok(mut list) = lists.get_mut(tree.entity) else {
            continue;
        };
        // Swapped, not compared and copied: the frame's list gets the old one's
        // allocations to fill next frame.
        core::mem::swap(&mut *list, list_chosen);
        if !list.is_empty() {
            chosen.trees_shown.push(tree.entity);
        }
    }
    // Held far trees keep last frame's list.
    chosen.trees_shown.extend(
        visible
            .held
            .iter()
            .filter_map(|&i| table.entities.get(i as usize)),
    );
    // Group impostors: last frame's cleared, this frame's cut swapped in.
    for entity in chosen.impostors_shown.drain(..) {
        if let Ok(mut list) = lists.get_mut(entity) {
            list.clear();
        }
    }
    for (entity, list_chosen) in chosen.impostors.drawn_mut() {
        if let Ok(mut list) = lists.get_mut(*entity) {
            core::mem::swap(&mut *list, list_chosen);
            chosen.impostors_shown.push(*entity);
        }
    }
    diagnostics.draw_lists_stage_ms = start.elapsed().as_secs_f32() * 1000.0;
}
