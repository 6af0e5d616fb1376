//! Greedy graph coloring of the contacts: contacts of one color share no body that an
//! impulse can move, so a color can be swept in parallel and gives the same result as a
//! sequential Gauss-Seidel sweep in color order.

/// A contact as the coloring sees it: its two bodies, whether an impulse can move each of
/// them, and whether it belongs to the serial group.
#[derive(Clone, Copy, Debug)]
pub struct Node {
    /// Body i.
    pub i: u32,
    /// Body j.
    pub j: u32,
    /// An impulse can change body i's velocity.
    pub moves_i: bool,
    /// An impulse can change body j's velocity.
    pub moves_j: bool,
    /// A contact with a force-driven wall (see [`color`]).
    pub serial: bool,
}

/// The result of [`color`]: contact indices sorted by color, the color boundaries in that
/// order (`ranges[c]..ranges[c+1]`), and whether the last range is a serial group.
#[derive(Clone, Debug, Default)]
pub struct Coloring {
    /// Contact indices in color order (stable within a color).
    pub order: Vec<u32>,
    /// Color boundaries in `order`.
    pub ranges: Vec<u32>,
    /// The last range is the serial group, swept by one thread.
    pub serial_last: bool,
    colors: Vec<u32>,
    masks: Vec<u64>,
}

/// Colors `nodes` (in their order, greedily, smallest free color first) into `out`.
///
/// Contacts with a force-driven wall (which can move under an impulse) all conflict with
/// each other through the wall: colored, they took one color each (87 colors for a 5000-disk
/// compaction instead of 9), and every color costs the thread team a barrier. They go
/// instead, in their order, into a last range that one thread sweeps sequentially.
///
/// Each body keeps a 64-bit mask of the colors used by its contacts in the current pass;
/// contacts that find all 64 taken (a body with many contacts) wait for a second pass with
/// colors 64..128, and so on, so the color count is unbounded without per-body heap lists.
pub fn color(nodes: impl ExactSizeIterator<Item = Node> + Clone, n_bodies: usize, out: &mut Coloring) {
    const UNSET: u32 = u32::MAX;
    const SERIAL: u32 = u32::MAX - 1;
    let colors = &mut out.colors;
    colors.clear();
    colors.extend(nodes.clone().map(|n| if n.serial { SERIAL } else { UNSET }));
    let serial = colors.iter().filter(|&&c| c == SERIAL).count();
    let mut base = 0u32;
    let mut remaining = colors.len() - serial;
    let masks = &mut out.masks;
    while remaining > 0 {
        masks.clear();
        masks.resize(n_bodies, 0);
        for (n, c) in nodes.clone().zip(colors.iter_mut()) {
            if *c != UNSET {
                continue;
            }
            let mut used = 0u64;
            if n.moves_i {
                used |= masks[n.i as usize];
            }
            if n.moves_j {
                used |= masks[n.j as usize];
            }
            if used == u64::MAX {
                continue;
            }
            let bit = (!used).trailing_zeros();
            *c = base + bit;
            if n.moves_i {
                masks[n.i as usize] |= 1 << bit;
            }
            if n.moves_j {
                masks[n.j as usize] |= 1 << bit;
            }
            remaining -= 1;
        }
        base += 64;
    }
    // Smallest-free-color leaves no gap within a pass (a contact of color c saw every
    // color below c taken), but passes after the first start at 64, 128...: renumber
    // densely so the color count is the number of non-empty colors.
    let span = colors
        .iter()
        .filter(|&&c| c != SERIAL)
        .map(|&c| c + 1)
        .max()
        .unwrap_or(0) as usize;
    let mut dense = vec![UNSET; span];
    for &c in colors.iter().filter(|&&c| c != SERIAL) {
        dense[c as usize] = 0;
    }
    let mut n_colors = 0u32;
    for slot in dense.iter_mut().filter(|s| **s == 0) {
        *slot = n_colors;
        n_colors += 1;
    }
    for c in colors.iter_mut() {
        *c = if *c == SERIAL {
            n_colors
        } else {
            dense[*c as usize]
        };
    }
    let n_ranges = n_colors as usize + usize::from(serial > 0);
    out.ranges.clear();
    out.ranges.resize(n_ranges + 1, 0);
    for &c in colors.iter() {
        out.ranges[c as usize + 1] += 1;
    }
    for k in 0..n_ranges {
        out.ranges[k + 1] += out.ranges[k];
    }
    let mut fill = out.ranges.clone();
    out.order.clear();
    out.order.resize(colors.len(), 0);
    for (k, &c) in colors.iter().enumerate() {
        let slot = &mut fill[c as usize];
        out.order[*slot as usize] = k as u32;
        *slot += 1;
    }
    out.serial_last = serial > 0;
}

#[cfg(test)]
mod tests {
    use super::*;

    fn node(i: u32, j: u32, moves_j: bool) -> Node {
        Node {
            i,
            j,
            moves_i: true,
            moves_j,
            serial: false,
        }
    }

    /// A body with 130 contacts needs 130 colors (each pair shares it): three passes of 64,
    /// renumbered densely; contacts sharing only a fixed body all take color 0.
    #[test]
    fn colors_are_proper_dense_and_unbounded() {
        let star: Vec<Node> = (1..=130).map(|k| node(0, k, true)).collect();
        let mut out = Coloring::default();
        color(star.iter().copied(), 131, &mut out);
        assert_eq!(out.ranges.len(), 131, "one color per contact of the hub");
        assert!(out.ranges.windows(2).all(|w| w[1] - w[0] == 1));
        let fixed: Vec<Node> = (1..=10).map(|k| node(k, 0, false)).collect();
        color(fixed.iter().copied(), 11, &mut out);
        assert_eq!(out.ranges, vec![0, 10], "a shared fixed body is no conflict");
    }

    #[test]
    fn serial_contacts_form_the_last_range_in_their_order() {
        let mut nodes: Vec<Node> = (0..6).map(|k| node(k, 100, false)).collect();
        nodes[1].serial = true;
        nodes[4].serial = true;
        let mut out = Coloring::default();
        color(nodes.iter().copied(), 101, &mut out);
        assert!(out.serial_last);
        assert_eq!(out.ranges, vec![0, 4, 6]);
        assert_eq!(out.order, vec![0, 2, 3, 5, 1, 4]);
    }
}
