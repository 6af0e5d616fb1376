//! Reader of Siconos 2D frictional contact problems (fc2d text files).
//!
//! The layout, one item per line unless said otherwise:
//!
//! ```text
//! 2                      space dimension
//! nc                     number of contacts
//! 2                      matrix storage: sparse
//! n n                    matrix size, n = 2 nc
//! 2                      sparse layout: compressed columns
//! CSparse ...            a header line, then "n-by-n, nzmax: K nnz: K, 1-norm: X"
//!     col j : locations a to b     for each column j, followed by its entries,
//!       i : value                  one per line: row i, value W[i][j]
//! q_0 ... q_{n-1}        the free velocities, on one line
//! mu_0 ... mu_{nc-1}     the friction coefficients, on one line
//! ```
//!
//! A dense matrix (storage 0) follows `n n` with a line `n<TAB>n`, then `n` lines of `n`
//! values: Siconos writes its column-major storage in order, so line `j` is column `j`.
//!
//! Components are ordered normal first, then tangent, contact by contact. The files shipped
//! as test data are in `tests/data/fc2d/`.
//!
//! A file cut short must not read as a smaller or different problem: q and mu must hold
//! exactly `n` and `nc` values on their own lines, nothing but blank lines may follow, and the
//! text must end with a newline, so a cut inside the last number (which still parses as a
//! number) is an error. The contact count is checked against the file's length before
//! anything is allocated for it: every contact needs at least [`BYTES_PER_CONTACT`] bytes.

use std::path::Path;

use super::{Csc, Problem};
use crate::error::{Error, Result};

/// Largest fc2d file read (256 MiB, about 500,000 contacts); larger, or a device that never
/// ends, is refused before it fills the memory.
pub const MAX_FILE_BYTES: u64 = 256 << 20;

/// Fewest bytes one contact takes in a file: its two q values and its friction coefficient,
/// each at least one digit and one separator.
pub const BYTES_PER_CONTACT: usize = 6;

/// Reads a problem; every malformed input is an [`Error::Parse`] naming the line.
pub fn read(path: &Path) -> Result<Problem> {
    let text = crate::config::read_capped(path, MAX_FILE_BYTES, "an fc2d problem")?;
    parse(&text, path)
}

/// A cursor over the lines of the file.
struct Lines<'a> {
    lines: Vec<&'a str>,
    at: usize,
    path: &'a Path,
}

impl<'a> Lines<'a> {
    fn err(&self, message: impl Into<String>) -> Error {
        Error::Parse {
            path: self.path.to_path_buf(),
            line: self.at.min(self.lines.len()),
            message: message.into(),
        }
    }

    fn next(&mut self, what: &str) -> Result<&'a str> {
        while self.at < self.lines.len() {
            let l = self.lines[self.at].trim();
            self.at += 1;
            if !l.is_empty() {
                return Ok(l);
            }
        }
        Err(self.err(format!("file ends before {what}")))
    }

    /// The next integer token of the header, on its own line or several on one line.
    fn ints(&mut self, what: &str) -> Result<Vec<usize>> {
        let l = self.next(what)?;
        l.split_whitespace()
            .map(|t| {
                t.parse::<usize>()
                    .map_err(|_| self.err(format!("expected {what}, found `{}`", shown(t))))
            })
            .collect()
    }
}

/// `text` for an error message, cut to 60 characters: a damaged file may hold a line of
/// megabytes, which the message need not repeat.
fn shown(text: &str) -> String {
    match text.char_indices().nth(60) {
        Some((k, _)) => format!("{}...", &text[..k]),
        None => text.to_string(),
    }
}

fn finite(l: &Lines, t: &str, what: &str) -> Result<f64> {
    match t.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(l.err(format!(
            "expected a finite number for {what}, found `{}`",
            shown(t)
        ))),
    }
}

/// Storage kinds of a Siconos matrix file: dense (column-major, one column a line) and
/// sparse, whose layout 2 is compressed columns (CSparse).
const DENSE: usize = 0;
/// See [`DENSE`].
const SPARSE: usize = 2;
/// See [`DENSE`].
const SPARSE_CSC: usize = 2;

/// The `n x n` matrix of a sparse (CSparse) file.
fn sparse_matrix(l: &mut Lines, n: usize) -> Result<Csc> {
    let banner = l.next("the CSparse banner")?;
    if !banner.starts_with("CSparse") {
        return Err(l.err(format!("expected the CSparse banner, found `{}`", shown(banner))));
    }
    let size = l.next("the matrix size line")?;
    if !size.starts_with(&format!("{n}-by-{n}")) {
        return Err(l.err(format!("expected `{n}-by-{n}, ...`, found `{}`", shown(size))));
    }
    let mut col_start = vec![0usize; n + 1];
    let mut row_idx = Vec::new();
    let mut vals = Vec::new();
    for j in 0..n {
        let line = l.next(if j == 0 {
            "the first column"
        } else {
            "the next column"
        })?;
        let rest = line.strip_prefix("col ").ok_or_else(|| {
            l.err(format!(
                "expected `col {j} : locations a to b`, found `{}`",
                shown(line)
            ))
        })?;
        let mut it = rest.split_whitespace();
        let cj = it.next().and_then(|t| t.parse::<usize>().ok());
        let words: Vec<&str> = it.collect();
        let (a, b) = match (cj, words.as_slice()) {
            (Some(c), [":", "locations", a, "to", b]) if c == j => (a.parse::<usize>(), b.parse::<usize>()),
            _ => {
                return Err(l.err(format!(
                    "expected `col {j} : locations a to b`, found `{}`",
                    shown(line)
                )));
            }
        };
        let (a, b) = match (a, b) {
            (Ok(a), Ok(b)) if a == vals.len() && b + 1 >= a => (a, b),
            _ => return Err(l.err(format!("bad location range in `{}`", shown(line)))),
        };
        for _ in a..=b {
            let e = l.next("a matrix entry")?;
            let (i, v) = e
                .split_once(':')
                .ok_or_else(|| l.err(format!("expected `row : value`, found `{}`", shown(e))))?;
            let i = i
                .trim()
                .parse::<usize>()
                .map_err(|_| l.err(format!("bad row index in `{}`", shown(e))))?;
            if i >= n {
                return Err(l.err(format!("row index {i} out of range 0..{n}")));
            }
            row_idx.push(i);
            vals.push(finite(l, v.trim(), "a matrix entry")?);
        }
        col_start[j + 1] = vals.len();
    }
    Ok(Csc {
        n,
        col_start,
        row_idx,
        vals,
    })
}

/// The `n x n` matrix of a dense file (Siconos writes its column-major storage in order,
/// `n` values a line: line `j` is column `j`), its zeros left out.
fn dense_matrix(l: &mut Lines, n: usize) -> Result<Csc> {
    let mut col_start = vec![0usize; n + 1];
    let (mut row_idx, mut vals) = (Vec::new(), Vec::new());
    for j in 0..n {
        let line = l.next("a column of the dense matrix")?;
        let mut count = 0;
        for (i, t) in line.split_whitespace().enumerate() {
            let v = finite(l, t, "a matrix entry")?;
            if i < n && v != 0.0 {
                row_idx.push(i);
                vals.push(v);
            }
            count = i + 1;
        }
        if count != n {
            return Err(l.err(format!(
                "{count} values in column {j} of the dense matrix, expected {n}"
            )));
        }
        col_start[j + 1] = vals.len();
    }
    Ok(Csc {
        n,
        col_start,
        row_idx,
        vals,
    })
}

/// Parses the text of a problem (`path` only names it in errors).
pub fn parse(text: &str, path: &Path) -> Result<Problem> {
    let mut l = Lines {
        lines: text.lines().collect(),
        at: 0,
        path,
    };
    // Header integers: dimension, contacts, storage kind, rows, columns; then the sparse
    // layout (kind 2) or the dense size line (kind 0). Several may share a line.
    let mut head = Vec::new();
    while head.len() < 5 {
        head.extend(l.ints("the header (dimension, contacts, storage, size)")?);
    }
    let (dim, nc, kind, rows, cols) = (head[0], head[1], head[2], head[3], head[4]);
    let mut more = head.split_off(5);
    if dim != 2 {
        return Err(l.err(format!("space dimension {dim}: only 2D problems are supported")));
    }
    if nc == 0 {
        return Err(l.err("the problem has no contact"));
    }
    if nc > text.len() / BYTES_PER_CONTACT {
        return Err(l.err(format!(
            "{nc} contacts announced, but a file of {} bytes holds at most {} (a damaged header?)",
            text.len(),
            text.len() / BYTES_PER_CONTACT
        )));
    }
    if rows != 2 * nc || cols != 2 * nc {
        return Err(l.err(format!("matrix {rows} x {cols} does not match 2 x {nc} contacts")));
    }
    let n = rows;
    let w = match kind {
        DENSE => {
            while more.len() < 2 {
                more.extend(l.ints("the dense matrix's size line")?);
            }
            if more != [n, n] {
                return Err(l.err(format!("dense matrix size line {more:?}, expected [{n}, {n}]")));
            }
            dense_matrix(&mut l, n)?
        }
        SPARSE => {
            if more.is_empty() {
                more.extend(l.ints("the sparse layout")?);
            }
            if more != [SPARSE_CSC] {
                return Err(l.err(format!(
                    "matrix storage {kind}/{more:?}: only sparse compressed columns (2/2) and \
                     dense (0) are supported"
                )));
            }
            sparse_matrix(&mut l, n)?
        }
        _ => {
            return Err(l.err(format!(
                "matrix storage {kind}: only dense (0) and sparse compressed columns (2/2) are \
                 supported"
            )));
        }
    };
    let line = l.next("the vector q")?;
    // q then mu, each on its own line with exactly its number of values.
    let mut numbers = Vec::with_capacity(n + nc);
    for t in line.split_whitespace() {
        numbers.push(finite(&l, t, "q")?);
    }
    if numbers.len() != n {
        return Err(l.err(format!(
            "{} values on the line of q, expected {n} (2 x {nc} contacts)",
            numbers.len()
        )));
    }
    let line = l.next("the friction coefficients")?;
    for t in line.split_whitespace() {
        numbers.push(finite(&l, t, "mu")?);
    }
    if numbers.len() != n + nc {
        return Err(l.err(format!(
            "{} friction coefficients, expected {nc}",
            numbers.len() - n
        )));
    }
    if l.next("").is_ok() {
        return Err(l.err("text after the friction coefficients"));
    }
    if !text.ends_with('\n') {
        return Err(l.err(
            "the file does not end with a newline after the friction coefficients: it was \
             cut short (an incomplete copy or download?)",
        ));
    }
    let mu = numbers.split_off(n);
    if let Some(m) = mu.iter().find(|m| **m < 0.0) {
        return Err(l.err(format!("negative friction coefficient {m}")));
    }
    Ok(Problem {
        nc,
        w,
        q: numbers,
        mu,
    })
}
