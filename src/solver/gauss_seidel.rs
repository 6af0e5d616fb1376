//! The Gauss-Seidel driver of a step: builds the rows, leaves out open candidates, colors,
//! sweeps until the convergence tests stop it (on the calling thread or on a thread team),
//! gives deep contacts their local updates and stores the impulses (docs/method.md,
//! "Nonlinear Gauss-Seidel").

use std::time::Instant;

use glam::DVec3;

use super::color::{Coloring, Node, color};
use super::convergence::VelocityTest;
use super::ctx::{Ctx, Line};
use super::lanes::{avx, proper_colors, sweep_color_chunk};
use super::quads::{for_each_impulse, gather_packed, row_at, set_impulses};
use super::resident::Slot;
use super::rows::{self, BodyProps, FULL, Row, opening};
use super::single::{self, Single};
use super::sweep::Colors;
use super::update::{CHUNK, sweep_chunk, update};
use super::{Method, SolveStats, SolverParams, team};
use crate::contact::Contact;

/// One Gauss-Seidel sweep over `rows` in order, where consecutive `ranges` are colors
/// (a single range for plain order), on the calling thread. Returns the chunked sums
/// (change^2, impulse^2); [`team`] sweeps colors on several threads with the same
/// chunks and the same order of summation. `colors` ranges from the first are colors
/// proper (rows that share no movable body); the others are swept row by row.
fn sweep(rows: &mut [Row], ranges: &[u32], colors: usize, ctx: Ctx) -> (f64, f64) {
    let mut total = (0.0, 0.0);
    for (c, w) in ranges.windows(2).enumerate() {
        let part = &mut rows[w[0] as usize..w[1] as usize];
        for ch in part.chunks_mut(CHUNK) {
            // SAFETY: one thread; indices checked by `rows::build`; rows of a color share no
            // movable body.
            let (d, r) = if c < colors {
                unsafe { sweep_color_chunk(ch, ctx) }
            } else {
                unsafe { sweep_chunk(ch, ctx) }
            };
            total.0 += d;
            total.1 += r;
        }
    }
    total
}

/// Scratch buffers of the Gauss-Seidel sweeps, kept between steps so that a step
/// allocates nothing once sizes settle.
#[derive(Clone, Debug, Default)]
pub struct Workspace {
    rows: Vec<Row>,
    props: Vec<BodyProps>,
    sorted: Vec<Row>,
    coloring: Coloring,
    /// Contact index of each swept row when some rows are parked.
    active: Vec<u32>,
    /// Rows left out of the sweeps ([`SolverParams::open_skip`]).
    parked: Vec<Row>,
    /// The velocity test's copy of the last iterate.
    iterate: Vec<Line>,
    /// The velocities as the sweeps keep them ([`Line`]): copied from the step's
    /// velocities before the sweeps and back after them.
    lines: Vec<Line>,
    /// Where the last solve's time went ([`SolveTimes`]).
    pub(super) times: SolveTimes,
    /// Contacts deeper than the deep-update threshold, in contact order (`rows::build`).
    deep: Vec<u32>,
    /// The place of each swept contact in the color order, when there are deep contacts.
    inverse: Vec<u32>,
    /// The deep contacts' rows, updated as plain rows while the others stay packed.
    deep_copies: Vec<Row>,
    /// The body table was given for the next solve ([`Workspace::give_bodies`]).
    props_given: bool,
    /// The sweeps' thread team, kept from step to step.
    team: Slot,
    /// The `f32` sweeps' copy ([`super::single`]), when they run.
    single: Single,
    /// Each row's bodies' figures for the `f32` sweeps, from the rows' build
    /// ([`rows::ColorRows::figures`]).
    figures: Vec<[f32; 6]>,
}

/// The swept rows of the deep contacts `candidates` (contact indices, ascending) that carry
/// a normal impulse (rows packed four at a time in the first `packed` color ranges), in
/// sweep order: the rows whose contact is deeper than the threshold.
/// Found through the candidates rather than by a pass over every row, which read each
/// row's contact in color order, out of the cache at 50,000 disks (docs/benchmarks.md,
/// "Sample size").
fn deep_rows(
    candidates: &[u32],
    rows: &[Row],
    (ranges, packed): (&[u32], usize),
    order: Option<&[u32]>,
    active: Option<&[u32]>,
    inverse: &mut Vec<u32>,
) -> Vec<usize> {
    if candidates.is_empty() {
        return Vec::new();
    }
    if let Some(o) = order {
        inverse.clear();
        inverse.resize(o.len(), 0);
        for (m, &k) in o.iter().enumerate() {
            inverse[k as usize] = m as u32;
        }
    }
    let mut deep: Vec<usize> = candidates
        .iter()
        .filter_map(|&c| {
            // Parked contacts have no row; `active` lists the swept ones in contact order.
            let k = match active {
                Some(a) => a.binary_search(&c).ok()?,
                None => c as usize,
            };
            Some(if order.is_some() { inverse[k] as usize } else { k })
        })
        .filter(|&m| row_at(rows, ranges, packed, m).rn > 0.0)
        .collect();
    deep.sort_unstable();
    deep
}

/// Wall time of the parts of one Gauss-Seidel solve (s): the fixed parts (`setup`: rows,
/// parking, coloring, color order, vector packing and the velocities' copy; `store`: the
/// impulses written back and the velocities copied back)
/// beside the iterations (`sweeps`) and the deep contacts' updates (`deep`). Other methods
/// count their whole solve as `sweeps`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SolveTimes {
    /// Rows, parking, coloring, color order, vector packing, the velocities' copy.
    pub setup: f64,
    /// The iterations.
    pub sweeps: f64,
    /// The deep contacts: finding them and their local updates.
    pub deep: f64,
    /// Writing the impulses back to the contacts and the velocities back to the step's.
    pub store: f64,
}

impl Workspace {
    /// The coloring of the last colored solve (empty ranges after another method).
    pub fn coloring(&self) -> &Coloring {
        &self.coloring
    }

    /// Where the last solve's time went.
    pub fn times(&self) -> SolveTimes {
        self.times
    }

    /// Gives the next solve its table of body properties: each disk's inverse mass, `r / I`
    /// and radius from `disks`, then `n_walls` walls (which no row of the table moves).
    /// Filled in one pass over the bodies, not by the rows' build at two scattered bodies
    /// per contact (docs/benchmarks.md, "One line per disk"). The contacts' records must
    /// carry the same figures: the engine passes those detection made them from
    /// (`contact::detect::Neighbours::disk_figures`).
    pub fn give_bodies(&mut self, disks: impl Iterator<Item = (f64, f64, f64)>, n_walls: usize) {
        self.props.clear();
        self.props
            .extend(disks.map(|(inv_mass, k, lever)| BodyProps::of(inv_mass, k, lever)));
        self.props
            .resize(self.props.len() + n_walls, BodyProps::default());
        self.props_given = true;
    }

    /// Forgets the coloring of the last solve, as a solve by another method must.
    pub(super) fn clear_coloring(&mut self) {
        self.times = SolveTimes::default();
        self.coloring.ranges.clear();
        self.coloring.order.clear();
        self.coloring.serial_last = false;
    }
}

/// Solves the contact problem by Gauss-Seidel: plain Gauss-Seidel sweeps the contacts in
/// their order, colored Gauss-Seidel colors them first ([`color`]) and sweeps the colors
/// in order, on a thread team when the problem is large enough. Unlike Jacobi it needs no
/// free velocities: `gv` carries every change from one update to the next.
pub(super) fn solve(
    params: &SolverParams,
    contacts: &mut [Contact],
    gv: &mut [DVec3],
    work: &mut Workspace,
    given: Option<Colors>,
) -> SolveStats {
    let t_setup = Instant::now();
    work.clear_coloring();
    let n_bodies = gv.len();
    let deep_gap = if params.deep_updates() {
        params.deep_gap
    } else {
        f64::INFINITY
    };
    let parking = params.open_skip > 0.0;
    let parked = parking.then_some(rows::Parking {
        gv,
        open_skip: params.open_skip,
        active: &mut work.active,
        parked: &mut work.parked,
    });
    let colored = params.method == Method::ColoredGs;
    let given = given.filter(|_| colored);
    assert!(
        !work.props_given || work.props.len() == n_bodies,
        "a body table given for other bodies"
    );
    // Colored here, and swept from a copy in color order.
    let recolored = colored && given.is_none();
    // The f32 sweeps take the rows plain and in color order; a serial group keeps the f64
    // sweeps (given colors say so now; colors made here, once made).
    let single_asked = colored && single::enabled() && !given.is_some_and(|g| g.serial_last);
    let avx = avx() && !single_asked;
    let frictionless = rows::build(
        contacts,
        n_bodies,
        deep_gap,
        &mut work.rows,
        (!std::mem::take(&mut work.props_given)).then_some(&mut work.props),
        &mut work.deep,
        parked,
        given.map(|g| rows::ColorRows {
            ranges: g.ranges,
            // Every color but the serial group, packed for the AVX sweeps.
            packed: if avx {
                proper_colors(g.ranges, g.serial_last)
            } else {
                0
            },
            out: &mut work.coloring.ranges,
            figures: single_asked.then_some(&mut work.figures),
        }),
    );
    let whole = [0, work.rows.len() as u32];
    if let Some(g) = given {
        // Colors left empty by the parking go: each costs the team a barrier.
        let r = &mut work.coloring.ranges;
        work.coloring.serial_last = g.serial_last && r.len() > 1 && r[r.len() - 1] > r[r.len() - 2];
        r.dedup();
    } else if colored {
        let props = &work.props;
        let nodes = work.rows.iter().map(|r| {
            let serial = r.j == FULL;
            Node {
                i: r.i,
                j: r.j,
                moves_i: !serial && props[r.i as usize].movable(),
                moves_j: !serial && props[r.j as usize].movable(),
                serial,
            }
        });
        color(nodes, n_bodies, &mut work.coloring);
    }
    let proper_colors = if colored {
        proper_colors(&work.coloring.ranges, work.coloring.serial_last)
    } else {
        0
    };
    let single = single_asked && !work.coloring.serial_last;
    let quads = colored && avx;
    // The color ranges whose rows are packed four at a time, from the copy in color order
    // to the store: the sweeps, the deep updates and the store read them in place.
    let packed = if quads { proper_colors } else { 0 };
    // Rows given in color order were packed as they were built.
    if recolored {
        let c = &work.coloring;
        gather_packed(&work.rows, &c.order, &c.ranges, packed, &mut work.sorted);
    }
    let (rows, ranges, serial_last) = if recolored {
        let c = &work.coloring;
        (&mut work.sorted, &c.ranges[..], c.serial_last)
    } else if colored {
        let c = &work.coloring;
        (&mut work.rows, &c.ranges[..], c.serial_last)
    } else {
        (&mut work.rows, &whole[..], false)
    };
    work.lines.clear();
    work.lines.extend(gv.iter().map(|&v| Line::of(v)));
    let ctx = Ctx {
        gv: work.lines.as_mut_ptr(),
        props: work.props.as_ptr(),
        contacts: contacts.as_mut_ptr(),
        relax: 1.0,
        quads,
        frictionless: quads && frictionless,
    };
    let mut stats = SolveStats {
        colors: if colored { (ranges.len() - 1) as u32 } else { 0 },
        ..Default::default()
    };
    let threads = params.team_size();
    if single {
        // Rows built in color order carry their figures; a copy in color order reads them
        // from the body table.
        let figures = (!recolored).then_some(&work.figures[..]);
        work.single.fill(rows, ranges, &work.props, figures, &work.lines);
    }
    let t_sweeps = Instant::now();
    // SAFETY: no sweep runs yet.
    let start = unsafe { std::slice::from_raw_parts(ctx.gv, n_bodies) };
    let mut velocity = VelocityTest::new(params, start, &mut work.iterate);
    // The test's first reference, when it applies from the first iteration: the f32 copy.
    if single && params.velocity_tol > 0.0 && params.gauss_seidel.relax_after == 0 {
        let lines = &work.single.lines;
        // SAFETY: nothing else holds the test yet.
        unsafe { velocity.share().keep(|k| lines[k].wide()) };
    }
    let props = &work.props[..];
    // `settled`: the velocity test's answer after iteration `it`, from the caller (on a
    // team each member tests its own bodies).
    let mut done = |it: u32, d2: f64, r2: f64, settled: bool| {
        // Between two tests (solver.check_every) the sums are recorded, the step goes on.
        let check = params.checks_at(it);
        if stats.record(it, d2, r2, params) && check {
            return true;
        }
        stats.converged = check && settled;
        stats.converged
    };
    if single {
        let s = &mut work.single;
        let lines32 = s.lines.as_mut_ptr();
        if threads > 1 && contacts.len() >= params.parallel_min {
            let team = work.team.get(threads);
            let velocity = velocity.share();
            let swept = team::Swept::Groups(&mut s.groups, lines32);
            team::sweep_iterations(swept, &s.ranges, false, ctx, team, params, velocity, done);
        } else {
            for it in 1..=params.max_iter {
                // SAFETY: one thread; indices checked by `rows::build`; rows of a color share
                // no movable body; `single::enabled` checked AVX-512F.
                let (d2, r2) = unsafe { s.sweep(params.relax_at(it)) };
                let share = velocity.share();
                let settled = share.runs_at(it)
                    // SAFETY: between sweeps, one thread; the copy holds every body.
                    && unsafe { share.bodies_f32(it, lines32, props.as_ptr(), 0..n_bodies) };
                if done(it, d2, r2, settled) {
                    break;
                }
            }
        }
        s.finish(rows, ranges, &mut work.lines);
    } else if colored && threads > 1 && contacts.len() >= params.parallel_min {
        let team = work.team.get(threads);
        let velocity = velocity.share();
        team::sweep_iterations(
            team::Swept::Rows(rows),
            ranges,
            serial_last,
            ctx,
            team,
            params,
            velocity,
            done,
        );
    } else {
        for it in 1..=params.max_iter {
            let ctx = Ctx {
                relax: params.relax_at(it),
                ..ctx
            };
            let (d2, r2) = sweep(rows, ranges, proper_colors, ctx);
            // SAFETY: between sweeps, when nothing writes the velocities.
            let gv = unsafe { std::slice::from_raw_parts(ctx.gv, n_bodies) };
            // Kept every iteration: a test compares the iterate with the one just before it.
            let settled = velocity.settled(it, gv, props);
            if done(it, d2, r2, settled) {
                break;
            }
        }
    }
    let t_deep = Instant::now();
    // Rows given in color order are swept where they were built.
    let order = recolored.then_some(&work.coloring.order[..]);
    let active = parking.then_some(&work.active[..]);
    if params.deep_updates() {
        let deep = deep_rows(
            &work.deep,
            rows,
            (ranges, packed),
            order,
            active,
            &mut work.inverse,
        );
        stats.deep = deep.len() as u32;
        let ctx = Ctx { relax: 1.0, ..ctx };
        // Updated as plain copies, in the same order, then their impulses put back.
        let copies = &mut work.deep_copies;
        copies.clear();
        copies.extend(deep.iter().map(|&m| row_at(rows, ranges, packed, m)));
        for _ in 0..params.deep_sweeps {
            for r in copies.iter_mut() {
                // SAFETY: no other sweep runs; the row's bodies are in range (checked in rows::build).
                unsafe {
                    update::<false>(r, ctx);
                }
            }
        }
        for (&m, r) in deep.iter().zip(copies.iter()) {
            set_impulses(rows, ranges, packed, m, r.rn, r.rt);
        }
    }
    let t_store = Instant::now();
    // Counted with the store, a fixed part, rather than with the deep contacts' updates.
    for (v, l) in gv.iter_mut().zip(&work.lines) {
        *v = l.v;
    }
    for_each_impulse(rows, ranges, packed, |m, j, rn, rt| {
        // Rows marked FULL were updated in their contact.
        if j != FULL {
            let c = &mut contacts[rows::contact_of(m, order, active)];
            c.rn = rn;
            c.rt = rt;
        }
    });
    work.times = SolveTimes {
        setup: (t_sweeps - t_setup).as_secs_f64(),
        sweeps: (t_deep - t_sweeps).as_secs_f64(),
        deep: (t_store - t_deep).as_secs_f64(),
        store: t_store.elapsed().as_secs_f64(),
    };
    if parking && work.parked.iter().any(|r| opening(r, gv) < 0.0) {
        // A parked contact would close: solve again with every contact, from the
        // impulses and velocities reached, so that none is missed.
        let every = SolverParams {
            open_skip: 0.0,
            ..*params
        };
        let first = work.times;
        let again = solve(&every, contacts, gv, work, given);
        let t = &mut work.times;
        t.setup += first.setup;
        t.sweeps += first.sweeps;
        t.deep += first.deep;
        t.store += first.store;
        return SolveStats {
            iterations: stats.iterations + again.iterations,
            unparked: true,
            ..again
        };
    }
    stats
}
