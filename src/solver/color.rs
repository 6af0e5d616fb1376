//! Greedy graph coloring of the contacts: contacts of one color share no body that an
//! impulse can move, so a color can be swept in parallel and gives the same result as a
//! sequential Gauss-Seidel sweep in color order.

use crate::contact::Contact;

/// Colors `contacts` (in their current order, greedily, smallest free color first) and
/// reorders them by color, stably. Returns the start offsets of each color
/// (`ranges[c]..ranges[c+1]`).
///
/// Each body keeps a 64-bit mask of the colors used by its contacts in the current pass;
/// contacts that find all 64 taken (a wall with many contacts) wait for a second pass with
/// colors 64..128, and so on, so the color count is unbounded without per-body heap lists.
pub fn color_contacts(contacts: &mut Vec<Contact>, n_bodies: usize, masks: &mut Vec<u64>) -> Vec<u32> {
    const UNSET: u32 = u32::MAX;
    for c in contacts.iter_mut() {
        c.color = UNSET;
    }
    let mut base = 0u32;
    let mut remaining = contacts.len();
    while remaining > 0 {
        masks.clear();
        masks.resize(n_bodies, 0);
        for c in contacts.iter_mut().filter(|c| c.color == UNSET) {
            let mut used = 0u64;
            if c.moves_i() {
                used |= masks[c.i as usize];
            }
            if c.moves_j() {
                used |= masks[c.j as usize];
            }
            if used == u64::MAX {
                continue;
            }
            let bit = (!used).trailing_zeros();
            c.color = base + bit;
            if c.moves_i() {
                masks[c.i as usize] |= 1 << bit;
            }
            if c.moves_j() {
                masks[c.j as usize] |= 1 << bit;
            }
            remaining -= 1;
        }
        base += 64;
    }
    // Passes after the first leave gaps (colors a pass never used): renumber densely so the
    // color count is the number of non-empty colors.
    let span = contacts.iter().map(|c| c.color + 1).max().unwrap_or(0) as usize;
    let mut dense = vec![UNSET; span];
    for c in contacts.iter() {
        dense[c.color as usize] = 0;
    }
    let mut n_colors = 0usize;
    for slot in dense.iter_mut().filter(|s| **s == 0) {
        *slot = n_colors as u32;
        n_colors += 1;
    }
    for c in contacts.iter_mut() {
        c.color = dense[c.color as usize];
    }
    let mut ranges = vec![0u32; n_colors + 1];
    for c in contacts.iter() {
        ranges[c.color as usize + 1] += 1;
    }
    for k in 0..n_colors {
        ranges[k + 1] += ranges[k];
    }
    let mut fill = ranges.clone();
    let mut sorted = vec![Contact::default(); contacts.len()];
    for c in contacts.iter() {
        let slot = &mut fill[c.color as usize];
        sorted[*slot as usize] = *c;
        *slot += 1;
    }
    *contacts = sorted;
    ranges
}
