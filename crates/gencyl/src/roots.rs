//! Root finding: closed-form quadratics and a guaranteed root isolator for smooth functions.

use arrayvec::ArrayVec;

use crate::real::{Dual, Interval, Real, Taylor};

/// Real roots of `a x^2 + b x + c`, ascending, by the cancellation-free formula
/// `q = -(b + sign(b) sqrt(b^2 - 4ac)) / 2`, roots `q/a` and `c/q`. Degrades to the linear case
/// when `a = 0`; a double root is returned once.
pub fn quadratic_roots(a: f64, b: f64, c: f64) -> ArrayVec<f64, 2> {
    let mut out = ArrayVec::new();
    if a == 0.0 {
        if b != 0.0 {
            out.push(-c / b);
        }
        return out;
    }
    let disc = b * b - 4.0 * a * c;
    if disc < 0.0 {
        return out;
    }
    let q = -0.5 * (b + b.signum() * disc.sqrt());
    if q == 0.0 {
        // b = 0 and c = 0: double root at 0.
        out.push(0.0);
        return out;
    }
    let (r0, r1) = (q / a, c / q);
    let (lo, hi) = if r0 <= r1 { (r0, r1) } else { (r1, r0) };
    out.push(lo);
    if hi != lo {
        out.push(hi);
    }
    out
}

/// Most roots [`isolate_roots`] reports on one interval.
pub const MAX_ROOTS: usize = 16;

/// A smooth real function of one variable that can also be enclosed over an interval.
///
/// `eval` is written once over [`Real`]; [`isolate_roots`] calls it with `f64` and `Dual<f64>`
/// for values and slopes, with `Dual<Taylor>` for enclosures of the function and its
/// derivative over a subinterval, and with `Taylor` for the function's alone (which must be the
/// value part of the pair: `eval` may not tell the two types apart)
/// ([`isolate_roots_reference`]: second-order duals of [`Interval`]s).
pub trait Function1D {
    /// `f(u)` over any scalar.
    fn eval<T: Real>(&self, u: T) -> T;
}

/// Settings of [`isolate_roots`].
#[derive(Clone, Copy, Debug)]
pub struct IsolateOptions {
    /// Subintervals narrower than this are no longer split: they are resolved by a sign test,
    /// or accepted as a tangential (double) root when `|f|` at their midpoint is at most
    /// `tangent_tolerance`.
    pub min_width: f64,
    /// See `min_width`.
    pub tangent_tolerance: f64,
    /// Safety cap on the cells examined per call (each takes one or two enclosures).
    pub max_evaluations: usize,
    /// Whether `f` is typically U-shaped on the interval (positive at both ends, negative in
    /// the middle: a ray through a fiber). Then a negative value at the midpoint splits the
    /// interval at once about the parabola through the ends and the midpoint, without an
    /// enclosure of the whole interval.
    pub u_shaped: bool,
}

impl Default for IsolateOptions {
    fn default() -> Self {
        IsolateOptions {
            min_width: 1e-10,
            tangent_tolerance: 1e-9,
            max_evaluations: 4000,
            u_shaped: false,
        }
    }
}

/// Finds every root of `f` in `[lo, hi]`, ascending, by subdivision with rigorous enclosures:
/// a subinterval whose enclosure of `f` excludes 0 holds no root and is dropped; one whose
/// enclosure of `f'` excludes 0 is monotone and holds a root exactly when `f` changes sign
/// between its ends, found by safeguarded Newton iteration to full precision; others are split.
/// The enclosures are rigorous, so no simple root is missed; what the method cannot decide is
/// only a tangential root narrower than `min_width` (see [`IsolateOptions`]).
///
/// The enclosures come from one evaluation of `f` over the subinterval in first-order Taylor
/// models with a dual part ([`Taylor`], [`Dual`]): `f ~ c0 + s0 t` and `f' ~ c1 + s1 t` plus
/// remainders that shrink like the square of the width, so the enclosures are the true ranges
/// up to second order and wide subintervals are decided at once. A subinterval that neither
/// test decides usually holds a critical point of `f` (the minimum between the two hits of a
/// ray, say): it is cut at the zero `m - h c1/s1` of the linear model of `f'` (`u = m + h t`)
/// into two sides that are
/// then monotone and a narrow middle where `f` keeps one sign, three cells where halving would
/// take five to seven. Otherwise it is halved. With [`IsolateOptions::u_shaped`] the first
/// cells may come from point values instead (`u_shaped_cells`), and Newton's method then
/// starts in a monotone cell from the parabola's estimate of its root where it has one; the
/// cells of such a U may share one model of `f'` over all of it (`UShape`). A cell
/// with one sign at both ends is first enclosed by the model of `f` alone (a third of the
/// work), which is the pair's value part to the bit: where it excludes zero the cell is done,
/// as the pair would have decided. Where neither decides such a cell and the model of `f'`
/// puts a critical point inside, `f` there (enclosed) and that model bound `f` over the cell
/// to higher order than the value model (`slope_bound`): a ray passing a fiber at a graze
/// is ruled out before the cell is split.
///
/// Returns whether the evaluation budget sufficed.
pub fn isolate_roots<F: Function1D>(
    f: &F,
    lo: f64,
    hi: f64,
    opts: &IsolateOptions,
    out: &mut ArrayVec<f64, MAX_ROOTS>,
) -> bool {
    let first = first_cells(f, lo, hi, opts, FirstRoot::Both);
    let found = isolate_in_cells(f, &first.cells, first.hints, opts, out);
    if found.overflow && found.complete {
        // More roots than `out` holds: those beyond it are lost, and the search is counted
        // as one that reached its bound.
        crate::budget::note_exhausted();
    }
    found.complete && !found.overflow
}

/// What [`isolate_in_cells`] reports besides the roots.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Isolated {
    /// Whether the evaluation budget sufficed (a search that exhausted it is counted).
    pub complete: bool,
    /// Whether a root found had no room left in the output (more than [`MAX_ROOTS`]; those
    /// beyond are lost, and the caller counts or splits the search).
    pub overflow: bool,
}

/// The cells [`isolate_roots`] starts from on `[lo, hi]`, in ascending order: the whole
/// interval, or with [`IsolateOptions::u_shaped`] the cells of `u_shaped_cells`; and what
/// its samples tell their isolation ([`Hints`]: estimates of roots, where Newton's method
/// starts in a cell that holds one, and whether `f` dipped inside). The cells may be isolated
/// one by one, in any order, by [`isolate_in_cells`]: a query that wants only the nearest
/// crossing along a ray takes them by distance and stops early. Such a query names the end
/// of `[lo, hi]` whose root it wants first (`first`): the cut that splits off the other root
/// waits ([`PendingCut`]), and the cells beyond the first root's are one until it is made.
pub(crate) fn first_cells<F: Function1D>(
    f: &F,
    lo: f64,
    hi: f64,
    opts: &IsolateOptions,
    first: FirstRoot,
) -> FirstCells {
    let point = |u: f64| f.eval(u);
    let (flo, fhi) = (point(lo), point(hi));
    if opts.u_shaped {
        u_shaped_cells(&point, (lo, hi), (flo, fhi), first)
    } else {
        let mut cells = ArrayVec::new();
        cells.push((lo, hi, flo, fhi));
        FirstCells {
            cells,
            hints: Hints::NONE,
            pending: None,
        }
    }
}

/// Which root of a U-shaped interval a query wants first ([`first_cells`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum FirstRoot {
    /// Both: every cut is made at once.
    Both,
    /// The one nearer the interval's lower end.
    Low,
    /// The one nearer its upper end.
    High,
}

/// What [`first_cells`] returns.
pub(crate) struct FirstCells {
    /// `(a, b, f(a), f(b))`, ascending and adjacent.
    pub cells: ArrayVec<Cell, 3>,
    /// What the values sampled to place them tell their isolation.
    pub hints: Hints,
    /// The cut left for later, with the index of the cell it splits.
    pub pending: Option<(usize, PendingCut)>,
}

/// A cut of a U-shaped interval that waits ([`first_cells`] with [`FirstRoot::Low`] or
/// [`FirstRoot::High`]): the point `x` where `f < 0` (and `f(x)`) and the parabola's estimate
/// `r` of the root on the side not yet cut. [`PendingCut::make`] gives the cells and hints
/// that cutting at once would have given, to the bit.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PendingCut {
    x: f64,
    fx: f64,
    r: f64,
    /// Whether the side not yet cut is the upper one.
    upper: bool,
}

impl PendingCut {
    /// Cuts `cell` (the one [`FirstCells::pending`] names, of the cells that came with
    /// `hints`): its cells, ascending, and the hints with this side's estimate of its root.
    pub(crate) fn make(
        self,
        f: &impl Function1D,
        (a, b, fa, fb): Cell,
        hints: Hints,
    ) -> (ArrayVec<Cell, 2>, Hints) {
        let point = |u: f64| f.eval(u);
        let mut cells = ArrayVec::new();
        let mut guesses = hints.guesses;
        let x = (self.x, self.fx);
        if self.upper {
            // `a` is the lower side's cut point `p`.
            let ((q, fq), right) = cut_side(&point, (b, fb), x, self.r);
            if a < q {
                cells.push((a, q, fa, fq));
            }
            cells.push((q, b, fq, fb));
            guesses[1] = right.unwrap_or(self.r);
        } else {
            // `b` is the upper side's cut point `q`.
            let ((p, fp), left) = cut_side(&point, (a, fa), x, self.r);
            cells.push((a, p, fa, fp));
            if p < b {
                cells.push((p, b, fp, fb));
            }
            guesses[0] = left.unwrap_or(self.r);
        }
        (cells, Hints { guesses, ..hints })
    }
}

/// What the values [`first_cells`] samples tell [`isolate_in_cells`] about its cells.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Hints {
    /// Estimates of roots, NaN where there are none: Newton's method starts from one in a
    /// cell that holds it.
    pub guesses: [f64; 2],
    /// Whether the cells are one, the whole interval, with `f` sampled inside it below both
    /// ends' values and of their sign (the middle of a U that stays positive: a ray passing
    /// close by a fiber). A first-order model over it carries that dip in its remainder and
    /// seldom excludes zero, so the cell's isolation goes straight to the model of `f` and `f'`
    /// (whose value part is that model, to the bit). The roots are the same either way; on the
    /// elliptical ponytail's camera rays this takes 0.8% off the fiber tests' instructions
    /// (every cell with one sign at both ends took the value model first, and 777 of the 1,831
    /// failed on ranges that held no crossing).
    pub dips: bool,
    /// The U-shaped interval that was cut, where one was: its sides' cells may take one model
    /// of `f'` over all of it ([`UShape`]).
    pub shape: Option<UShape>,
}

impl Hints {
    /// No estimates.
    pub const NONE: Hints = Hints {
        guesses: [f64::NAN; 2],
        dips: false,
        shape: None,
    };

    /// The same estimates for part of the cells (the dip was sampled in the whole).
    pub fn for_part(self) -> Hints {
        Hints {
            dips: false,
            ..self
        }
    }
}

/// The roots of `f` in the given cells (ascending and disjoint but for shared ends), ascending,
/// as [`isolate_roots`] finds them, with the [`Hints`] of [`first_cells`].
pub(crate) fn isolate_in_cells<F: Function1D>(
    f: &F,
    cells: &[Cell],
    hints: Hints,
    opts: &IsolateOptions,
    out: &mut ArrayVec<f64, MAX_ROOTS>,
) -> Isolated {
    let value = |u: f64| {
        let r = f.eval(Dual::var(u));
        (r.v, r.d)
    };
    let point = |u: f64| f.eval(u);
    // The model of `f'` over the whole U-shaped interval, once a side has asked for it.
    let mut whole: Option<Slopes> = None;
    // Cells, processed left to right so roots come out ascending: pushed last first.
    let mut stack: ArrayVec<Cell, 256> = ArrayVec::new();
    stack.extend(cells.iter().rev().copied());
    let mut evaluations = 0;
    let mut complete = true;
    // Whether every root found had room in `out`.
    let mut room = true;
    while let Some((a, b, fa, fb)) = stack.pop() {
        evaluations += 1;
        if evaluations > opts.max_evaluations {
            // Out of budget: fall back to sign changes at the ends for what is left.
            if complete {
                crate::budget::note_exhausted();
            }
            complete = false;
            if let Some(r) = bracketed_root(&value, a, b, fa, fb) {
                room &= push_root(out, r);
            }
            continue;
        }
        // With one sign at both ends (the middle of a ray's chord through a fiber, a ray that
        // passes by), the enclosure of `f` alone, a third of the work of `f` and `f'`
        // together, often rules the cell out; it is the same as the value part of the pair.
        let one_sign = (fa > 0.0 && fb > 0.0) || (fa < 0.0 && fb < 0.0);
        // A side of a U-shaped interval, monotone by the model of `f'` over all of it: its root.
        if let Some(shape) = hints.shape
            && shape.side_near_parabola((a, b, fa, fb))
        {
            let slopes = whole
                .get_or_insert_with(|| {
                    evaluations += 1;
                    shape.slopes(f)
                })
                .on(a, b);
            if slopes.min > 0.0 {
                // An estimate in the cell, else the chord's zero.
                let start = hints.guesses.into_iter().find(|&g| g > a && g < b);
                let start = start.unwrap_or(a + (b - a) * (fa / (fa - fb)));
                if let Some(r) = bracketed_root_from(&value, &point, (a, b, fa, fb), start, slopes)
                {
                    room &= push_root(out, r);
                }
                continue;
            }
        }
        // The middle of a U-shaped interval (`f < 0` at both ends), where that model is at hand:
        // `f` falls, then rises, and stays below zero between.
        if fa < 0.0
            && fb < 0.0
            && let (Some(shape), Some(slopes)) = (hints.shape, whole)
            && shape.lo <= a
            && b <= shape.hi
            && slopes.keeps_negative((a, b, fa, fb))
        {
            continue;
        }
        // The whole interval, where the samples dipped: the pair at once.
        let dips = hints.dips && evaluations == 1;
        // `u = m + h t`, `t` in `[-1, 1]`: the models' slopes are in `t`.
        let var = Taylor::var(a, b);
        let (m, h) = (var.c, var.s);
        if one_sign && !dips && f.eval(var).enclosure().excludes_zero() {
            continue;
        }
        let Dual { v: model, d: slope } = f.eval(Dual::var(var));
        if model.enclosure().excludes_zero() {
            continue;
        }
        if slope.enclosure().excludes_zero() {
            // Newton's method from an estimate in the cell, else from the zero of the model's
            // linear part; `f` is monotone on the cell, and the model bounds `f'`.
            let start = hints
                .guesses
                .into_iter()
                .find(|&g| g > a && g < b)
                .unwrap_or(m - h * (model.c / model.s));
            let slopes = Slopes::of(m, h, slope);
            if let Some(r) = bracketed_root_from(&value, &point, (a, b, fa, fb), start, slopes) {
                room &= push_root(out, r);
            }
            continue;
        }
        let narrow = b - a <= opts.min_width || m <= a || m >= b;
        // Split around the predicted critical point, if it is well inside: the middle cell
        // reaches out to where the linear part of f' outweighs (four times) its remainder.
        let critical = m - h * (slope.c / slope.s);
        // With one sign at both ends and a critical point inside (a ray passing close by a
        // fiber): the value at it and the model of f' bound f to fourth order.
        if one_sign && a < critical && critical < b {
            let fy = f.eval(Taylor::var(critical, critical)).enclosure();
            let positive =
                |lo: f64, bound: f64| (Interval::cst(lo) + Interval::cst(bound)).lo > 0.0;
            let excluded = if fa > 0.0 {
                positive(fy.lo, slope_bound(slope, (m, h), critical, (a, b)))
            } else {
                positive(-fy.hi, slope_bound(-slope, (m, h), critical, (a, b)))
            };
            if excluded {
                continue;
            }
        }
        let half = (4.0 * slope.rho * h / slope.s.abs())
            .max(0.02 * h)
            .min(0.25 * h);
        let (p, q) = (critical - half, critical + half);
        if !narrow
            && (critical - m).abs() < 0.5 * h
            && a < p
            && p < q
            && q < b
            && stack.len() + 3 <= stack.capacity()
        {
            let (fp, fq) = (point(p), point(q));
            stack.push((q, b, fq, fb));
            stack.push((p, q, fp, fq));
            stack.push((a, p, fa, fp));
            continue;
        }
        if narrow || stack.len() + 2 > stack.capacity() {
            if let Some(r) = bracketed_root(&value, a, b, fa, fb) {
                room &= push_root(out, r);
            } else if point(m).abs() <= opts.tangent_tolerance
                && !out.last().is_some_and(|&l| m - l <= 2.0 * opts.min_width)
            {
                room &= push_root(out, m);
            }
            continue;
        }
        let fm = point(m);
        // Right half first so the left half is processed first: roots come out ascending.
        stack.push((m, b, fm, fb));
        stack.push((a, m, fa, fm));
    }
    // Roots from the budget fallback can come out of order.
    out.sort_by(f64::total_cmp);
    Isolated {
        complete,
        overflow: !room,
    }
}

/// A U-shaped interval that [`u_shaped_cells`] cut: `f` positive at its ends `lo` and `hi`,
/// negative at `x` between them. Its cells are the entry's side `[lo, p]`, the middle and the
/// exit's side `[q, hi]` (`p <= x <= q`, where `f` is negative too). Across a fiber `f'` is
/// close to linear on such an interval, and one model of `f'` over all of it usually proves
/// both sides monotone ([`Slopes::on`]) and the middle below zero ([`Slopes::keeps_negative`]):
/// one pair of models where each side took its own and the middle a model of `f`.
///
/// Each side decides from its own samples whether to ask for that model, so a query that
/// isolates one side (the nearest crossing, [`PendingCut`]) and one that isolates both take
/// the same steps on it, and find its root to the bit.
#[derive(Clone, Copy, Debug)]
pub(crate) struct UShape {
    lo: f64,
    hi: f64,
    flo: f64,
    fhi: f64,
    x: f64,
    fx: f64,
}

impl UShape {
    /// Whether `cell` is a side (`[lo, p]` or `[q, hi]`, with a sign change) whose values with
    /// the ends' and `x`'s are close to a parabola: through the four points `lo < y < z < hi`
    /// (the side's cut and `x`), the divided differences `d2 ~ f''/2` and `d3 ~ f'''/6` put
    /// `f'` within `3 |d3| H^2` of a line of slope `2 d2` over the half-width `H`, so its zero
    /// is known to within `1.5 |d3| H^2 / d2`; that must be under an eighth of the cut's
    /// distance from `x`, or the model would seldom prove the side monotone (and cost a pair
    /// for nothing). The eighth was measured: a quarter or a half took more pairs on wobbly
    /// U's than the side models did, and no fewer on fibers.
    fn side_near_parabola(&self, (a, b, fa, fb): Cell) -> bool {
        let UShape {
            lo,
            hi,
            flo,
            fhi,
            x,
            fx,
        } = *self;
        let ((y, fy), (z, fz), cut) = if a == lo && b <= x && fa > 0.0 && fb < 0.0 {
            ((b, fb), (x, fx), b)
        } else if b == hi && a >= x && fa < 0.0 && fb > 0.0 {
            ((x, fx), (a, fa), a)
        } else {
            return false;
        };
        let d = |(a, fa): (f64, f64), (b, fb): (f64, f64)| (fb - fa) / (b - a);
        let (d01, d12, d23) = (
            d((lo, flo), (y, fy)),
            d((y, fy), (z, fz)),
            d((z, fz), (hi, fhi)),
        );
        let (d012, d123) = ((d12 - d01) / (z - lo), (d23 - d12) / (hi - y));
        let d3 = (d123 - d012) / (hi - lo);
        let (d2, half) = (0.5 * (d012 + d123), 0.5 * (hi - lo));
        12.0 * d3.abs() * half * half <= d2 * (x - cut).abs()
    }

    /// The model of `f'` over `[lo, hi]`, from one pair of models.
    fn slopes<F: Function1D>(&self, f: &F) -> Slopes {
        let var = Taylor::var(self.lo, self.hi);
        let Dual { d: slope, .. } = f.eval(Dual::var(var));
        Slopes::of(var.c, var.s, slope)
    }
}

/// A lower bound of `f(x) - f(y)` for `x` in `[a, b]` (holding `y`), from the model
/// `f'(m + h t) in c + s' t + [-rho, rho]` (`t` in `[-1, 1]`, [`Taylor::var`]), that is
/// `f'(u) in c + s (u - m) + [-rho, rho]` with `s = s' / h` (an interval): with `tau = x - y` and
/// `g0 = c + s (y - m)` (the model's `f'` at `y`), `f(x) - f(y)` is the integral of `f'` from
/// `y`, at least `q(tau) = (g0 - rho) tau + s tau^2 / 2` for `tau >= 0` and
/// `(g0 + rho) tau + s tau^2 / 2` for `tau <= 0`. Each quadratic is bounded below by its
/// vertex value `-(g0 -+ rho)^2 / 2s` where `s > 0`, else (concave) by its values at the
/// ends; and by `q(0) = 0`. In interval arithmetic. Where `y` is `f`'s critical point
/// (`g0 ~ 0`) this is about `-rho^2 / 2s`: fourth order in the width (`rho ~ h^2`), where the
/// value model's own bound is second order (a ray that passes a fiber at a graze).
fn slope_bound(slope: Taylor, (m, h): (f64, f64), y: f64, (a, b): (f64, f64)) -> f64 {
    let i = |x: f64| Interval::exact(x, x);
    let (c, s, rho) = (i(slope.c), i(slope.s).div_cst(h), i(slope.rho));
    let g0 = c + s * (i(y) - i(m));
    let (right, left) = (g0 - rho, g0 + rho);
    let bound = if slope.s > 0.0 {
        let two_s = s.scale(2.0);
        fmin((-(right.sqr() / two_s)).lo, (-(left.sqr() / two_s)).lo)
    } else {
        let (t0, t1) = (i(a) - i(y), i(b) - i(y));
        let half = s.scale(0.5);
        fmin(
            (right * t1 + half * t1.sqr()).lo,
            (left * t0 + half * t0.sqr()).lo,
        )
    };
    if bound.is_nan() {
        f64::NEG_INFINITY
    } else {
        fmin(bound, 0.0)
    }
}

/// `min` of two numbers, NaN-free by the caller.
fn fmin(a: f64, b: f64) -> f64 {
    if a < b { a } else { b }
}

/// `max` of two numbers, NaN-free by the caller.
fn fmax(a: f64, b: f64) -> f64 {
    if a > b { a } else { b }
}

/// A cell of [`isolate_roots`]: `(a, b, f(a), f(b))`.
pub(crate) type Cell = (f64, f64, f64, f64);

/// The first cells of [`isolate_roots`] on `[lo, hi]` for a function that is typically
/// U-shaped there ([`IsolateOptions::u_shaped`]). Where `f` is positive at both ends and
/// negative at a point `x` between them, the parabola through the three values has zeros
/// `r1 < x < r2` near the two roots, and the interval is cut at `p = (r1 + x) / 2` and
/// `q = (x + r2) / 2` where `f` is still negative there (else at `x`): two sides that hold one
/// root each and are usually monotone, and a middle where `f` keeps its sign, decided by one
/// enclosure each instead of first enclosing the whole interval to find that split. `x` is the
/// midpoint `m`, or where `f(m) >= 0` (a ray through a fiber off the middle of its range) the
/// vertex of the parabola through `lo`, `m` and `hi` when that parabola dips below zero (one
/// more value; a ray that passes by seldom pays it). Only cut points where `f < 0`, so never
/// at a root; otherwise the whole interval, as for any function. Its hints: estimates of the
/// two roots (NaN without a cut), which start Newton's method closer to the roots than the
/// sides' linear models do (3% fewer instructions on the ponytail's elliptical fibers): on a
/// side that was cut, the zero of the parabola through its own ends and `x` (`local_zero`; on
/// the elliptical ponytail a median 5e-7 from the root, 1.1% fewer instructions in its fiber
/// tests), else `r1` or `r2`; and for the whole interval whether a value sampled inside lies
/// below both ends' ([`Hints::dips`]). With `first` naming one root, only its side is cut:
/// the rest is one cell, `[p, hi]` or `[lo, q]`, whose cut waits ([`PendingCut`]).
fn u_shaped_cells(
    point: &impl Fn(f64) -> f64,
    (lo, hi): (f64, f64),
    (flo, fhi): (f64, f64),
    first: FirstRoot,
) -> FirstCells {
    let mut cells = ArrayVec::new();
    // The whole interval, with the least value sampled inside it (NaN if none).
    let whole = |mut cells: ArrayVec<Cell, 3>, least: f64| {
        cells.push((lo, hi, flo, fhi));
        let hints = Hints {
            dips: least < fmin(flo, fhi),
            ..Hints::NONE
        };
        FirstCells {
            cells,
            hints,
            pending: None,
        }
    };
    let m = 0.5 * (lo + hi);
    if !(flo > 0.0 && fhi > 0.0 && lo < m && m < hi) {
        return whole(cells, f64::NAN);
    }
    let fm = point(m);
    let (x, fx) = if fm < 0.0 {
        (m, fm)
    } else {
        // The symmetric parabola f(m) + c1 (u - m) + c2 (u - m)^2, h = (hi - lo) / 2:
        // c2 = (f(lo) - 2 f(m) + f(hi)) / 2h^2, c1 = (f(hi) - f(lo)) / 2h, its vertex at
        // m - c1 / 2c2 with the value f(m) - c1^2 / 4c2.
        let h = 0.5 * (hi - lo);
        let (c2, c1) = (
            (flo - 2.0 * fm + fhi) / (2.0 * h * h),
            (fhi - flo) / (2.0 * h),
        );
        let v = m - c1 / (2.0 * c2);
        if !(c2 > 0.0 && fm - c1 * c1 / (4.0 * c2) < 0.0 && lo < v && v < hi) {
            return whole(cells, fm);
        }
        let fv = point(v);
        if !(fv < 0.0) {
            return whole(cells, fmin(fm, fv));
        }
        (v, fv)
    };
    // The parabola fx + b (u - x) + a (u - x)^2 through (lo, f(lo)), (x, f(x)), (hi, f(hi)):
    // with h1 = x - lo, h2 = hi - x and the slopes s1 = (f(lo) - f(x)) / h1,
    // s2 = (f(hi) - f(x)) / h2 (both positive), a = (s1 + s2) / (h1 + h2) and
    // b = (s2 h1 - s1 h2) / (h1 + h2); a > 0 > f(x), so b^2 - 4 a f(x) > 0, rounding aside.
    let (h1, h2) = (x - lo, hi - x);
    let (s1, s2) = ((flo - fx) / h1, (fhi - fx) / h2);
    let a = (s1 + s2) / (h1 + h2);
    let b = (s2 * h1 - s1 * h2) / (h1 + h2);
    let root = (b * b - 4.0 * a * fx).sqrt();
    let (r1, r2) = if a > 0.0 && root.is_finite() {
        (x + (-b - root) / (2.0 * a), x + (-b + root) / (2.0 * a))
    } else {
        (lo, hi)
    };
    let pending = |upper: bool, r: f64| PendingCut { x, fx, r, upper };
    let shape = UShape {
        lo,
        hi,
        flo,
        fhi,
        x,
        fx,
    };
    let (cells, guesses, pending) = match first {
        FirstRoot::Both => {
            let ((p, fp), left) = cut_side(point, (lo, flo), (x, fx), r1);
            let ((q, fq), right) = cut_side(point, (hi, fhi), (x, fx), r2);
            cells.push((lo, p, flo, fp));
            if p < q {
                cells.push((p, q, fp, fq));
            }
            cells.push((q, hi, fq, fhi));
            (cells, [left.unwrap_or(r1), right.unwrap_or(r2)], None)
        }
        FirstRoot::Low => {
            let ((p, fp), left) = cut_side(point, (lo, flo), (x, fx), r1);
            cells.push((lo, p, flo, fp));
            cells.push((p, hi, fp, fhi));
            (
                cells,
                [left.unwrap_or(r1), r2],
                Some((1, pending(true, r2))),
            )
        }
        FirstRoot::High => {
            let ((q, fq), right) = cut_side(point, (hi, fhi), (x, fx), r2);
            cells.push((lo, q, flo, fq));
            cells.push((q, hi, fq, fhi));
            (
                cells,
                [r1, right.unwrap_or(r2)],
                Some((0, pending(false, r1))),
            )
        }
    };
    FirstCells {
        cells,
        hints: Hints {
            guesses,
            dips: false,
            shape: Some(shape),
        },
        pending,
    }
}

/// One side's cut of [`u_shaped_cells`], the side of `end` (`lo` or `hi`): at
/// `y = (r + x) / 2` (`r` clamped to between `x` and `end`) where `f(y) < 0` and `y` is not
/// `end`, else at `x`; and the estimate of that side's root from the parabola through `end`,
/// the cut and `x` (`local_zero`), where the cut is not `x`.
fn cut_side(
    point: &impl Fn(f64) -> f64,
    (end, fend): (f64, f64),
    (x, fx): (f64, f64),
    r: f64,
) -> ((f64, f64), Option<f64>) {
    let lower = end < x;
    let y = 0.5
        * (if lower {
            r.clamp(end, x)
        } else {
            r.clamp(x, end)
        } + x);
    let fy = point(y);
    let inside = if lower { end < y } else { y < end };
    let (c, fc) = if fy < 0.0 && inside { (y, fy) } else { (x, fx) };
    let estimate = match (c == x, lower) {
        (true, _) => None,
        (false, true) => local_zero((end, fend), (c, fc), (x, fx)),
        (false, false) => local_zero((c, fc), (end, fend), (x, fx)),
    };
    ((c, fc), estimate)
}

/// The zero in `(a, b)` of the parabola through `(a, fa)`, `(b, fb)` and `(c, fc)` (`c` outside
/// `[a, b]`), if it has one there: with `t = u - a` and the divided differences
/// `d1 = (fb - fa) / (b - a)`, `d2 = ((fc - fb) / (c - b) - d1) / (c - a)`, the parabola is
/// `fa + (d1 - d2 (b - a)) t + d2 t^2`, solved without cancellation.
fn local_zero((a, fa): (f64, f64), (b, fb): (f64, f64), (c, fc): (f64, f64)) -> Option<f64> {
    let d1 = (fb - fa) / (b - a);
    let d2 = ((fc - fb) / (c - b) - d1) / (c - a);
    let (qa, qb, qc) = (d2, d1 - d2 * (b - a), fa);
    let disc = qb * qb - 4.0 * qa * qc;
    let k = -0.5 * (qb + disc.sqrt().copysign(qb));
    [k / qa, qc / k]
        .into_iter()
        .map(|t| a + t)
        .find(|&u| u > a && u < b)
}

/// A smooth map of the plane with enclosures over boxes, for [`isolate_roots_2d`].
pub trait Function2D {
    /// `F(x)` and its Jacobian `J[i][j] = dF_i/dx_j` at a point.
    fn jet(&self, x: [f64; 2]) -> ([f64; 2], [[f64; 2]; 2]);
    /// Enclosures over the box `[lo, hi]` of `F` and of `J`, and an enclosure of `F` at the box's
    /// centre (its value with the rounding bounded).
    fn enclose(&self, lo: [f64; 2], hi: [f64; 2]) -> Enclosure2;
}

/// What [`Function2D::enclose`] returns.
#[derive(Clone, Copy, Debug)]
pub struct Enclosure2 {
    /// `F` over the box.
    pub f: [Interval; 2],
    /// `J` over the box.
    pub j: [[Interval; 2]; 2],
    /// `F` at the centre.
    pub f_center: [Interval; 2],
    /// The variable to halve first, if the function knows its enclosures are unbounded because
    /// of it (a parameter range that reaches a singular point).
    pub split: Option<usize>,
}

/// Settings of [`isolate_roots_2d`].
#[derive(Clone, Copy, Debug)]
pub struct Isolate2D {
    /// Boxes narrower than this in both variables are not split: a root there (at a tangency,
    /// where the Jacobian is singular) is taken from Newton's method when it converges inside
    /// with a residual no larger than the Jacobian moves `F` across such a box.
    pub min_width: [f64; 2],
    /// Safety cap on boxes examined per call.
    pub max_boxes: usize,
}

/// Roots of [`isolate_roots_2d`] closer than this many `min_width`s in both variables are
/// taken for one: boxes at the rounding floor of `F` near a root all lead Newton's method to it.
const DEDUPE: f64 = 1e3;

/// An interval 2x2 matrix times an interval vector.
fn mat_vec(m: [[Interval; 2]; 2], x: [Interval; 2]) -> [Interval; 2] {
    [
        m[0][0] * x[0] + m[0][1] * x[1],
        m[1][0] * x[0] + m[1][1] * x[1],
    ]
}

/// Newton's method in two variables from `x`, kept inside `[lo, hi]`: the converged point, or
/// `None` if it leaves the box, stalls or the Jacobian is singular.
fn newton2<F: Function2D>(f: &F, mut x: [f64; 2], lo: [f64; 2], hi: [f64; 2]) -> Option<[f64; 2]> {
    for _ in 0..60 {
        let (g, j) = f.jet(x);
        let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
        if !(det.is_finite() && det != 0.0) {
            return None;
        }
        let step = [
            (g[0] * j[1][1] - g[1] * j[0][1]) / det,
            (g[1] * j[0][0] - g[0] * j[1][0]) / det,
        ];
        let next = [x[0] - step[0], x[1] - step[1]];
        if !(next[0] >= lo[0] && next[0] <= hi[0] && next[1] >= lo[1] && next[1] <= hi[1]) {
            return None;
        }
        let small = |k: usize| step[k].abs() <= 4.0 * f64::EPSILON * next[k].abs().max(1e-300);
        x = next;
        if small(0) && small(1) {
            return Some(x);
        }
    }
    Some(x)
}

/// Every root of `F` in the box `[lo, hi]`, by interval Newton in Krawczyk's form: with `c` the
/// box's centre and `Y` the inverse of the Jacobian there,
/// `K(X) = c - Y F(c) + (I - Y J(X)) (X - c)` holds every root in `X` (`J(X)` the Jacobian's
/// enclosure over the box). A box whose `F` enclosure excludes 0, or whose `K` misses it, holds
/// none; one whose `K` lies inside it holds exactly one, found by Newton's method from `c`;
/// otherwise the box is cut down to `K` and, unless that shrank it well, halved across its
/// wider side (relative to `min_width`). Roots in no particular order.
///
/// Returns whether the box budget sufficed.
pub fn isolate_roots_2d<F: Function2D>(
    f: &F,
    lo: [f64; 2],
    hi: [f64; 2],
    opts: &Isolate2D,
    out: &mut ArrayVec<[f64; 2], MAX_ROOTS>,
) -> bool {
    let (lo0, hi0) = (lo, hi);
    let mut stack: ArrayVec<([f64; 2], [f64; 2]), 128> = ArrayVec::new();
    stack.push((lo, hi));
    let mut boxes = 0;
    // Each root found blurs a neighbourhood: `DEDUPE` resolution widths, and at the rounding
    // floor of F the blur Newton's method reaches through. Another root found there is the same
    // root, and narrow boxes there are not examined again (they would all lead back to it).
    let mut blurs: ArrayVec<([f64; 2], [f64; 2]), MAX_ROOTS> = ArrayVec::new();
    let dedupe = |x: [f64; 2]| -> [f64; 2] {
        std::array::from_fn(|k| DEDUPE * opts.min_width[k].max(1e-15 * x[k].abs()))
    };
    let near = |blurs: &ArrayVec<([f64; 2], [f64; 2]), MAX_ROOTS>, x: [f64; 2]| {
        blurs
            .iter()
            .any(|(y, r)| (0..2).all(|k| (x[k] - y[k]).abs() <= r[k]))
    };
    let push = |out: &mut ArrayVec<[f64; 2], MAX_ROOTS>,
                blurs: &mut ArrayVec<([f64; 2], [f64; 2]), MAX_ROOTS>,
                x: [f64; 2],
                blur: [f64; 2]| {
        if !out.is_full() && !near(blurs, x) {
            out.push(x);
            let d = dedupe(x);
            blurs.push((x, [d[0].max(blur[0]), d[1].max(blur[1])]));
        }
    };
    while let Some((a, b)) = stack.pop() {
        boxes += 1;
        if boxes > opts.max_boxes {
            crate::budget::note_exhausted();
            return false;
        }

        // A box inside a found root's blur holds nothing new.
        if blurs
            .iter()
            .any(|(y, r)| (0..2).all(|k| a[k] >= y[k] - r[k] && b[k] <= y[k] + r[k]))
        {
            continue;
        }
        let xb = [Interval::exact(a[0], b[0]), Interval::exact(a[1], b[1])];
        let enc = f.enclose(a, b);
        if enc.f[0].excludes_zero() || enc.f[1].excludes_zero() {
            continue;
        }
        let c = [0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])];
        let jx = enc.j;
        let m = jx.map(|row| row.map(|e| e.value()));
        let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
        let narrow = (0..2).all(|k| b[k] - a[k] <= opts.min_width[k]);
        if narrow {
            // At the resolution of the enclosures (or of F's rounding, which can be coarser):
            // Newton's method from the centre decides. It may go as far as F's rounding blurs
            // the root (`|J^-1|` times the width of F's enclosure at a point) and a few box
            // widths, not farther: a neighbouring root is another box's.
            let w = opts.min_width;
            if near(&blurs, c) {
                continue;
            }
            let floor = |i: usize| enc.f_center[i].width();
            let reach: [f64; 2] = std::array::from_fn(|k| {
                let blur = if det.is_finite() && det != 0.0 {
                    let inv = [[m[1][1], -m[0][1]], [-m[1][0], m[0][0]]];
                    (inv[k][0].abs() * floor(0) + inv[k][1].abs() * floor(1)) / det.abs()
                } else {
                    0.0
                };
                4.0 * w[k].max(b[k] - a[k]) + 8.0 * blur
            });
            let lo = [(a[0] - reach[0]).max(lo0[0]), (a[1] - reach[1]).max(lo0[1])];
            let hi = [(b[0] + reach[0]).min(hi0[0]), (b[1] + reach[1]).min(hi0[1])];
            if let Some(x) = newton2(f, c, lo, hi) {
                // A root to the resolution of the box, or of F's own rounding (the width of
                // its enclosure at a point), whichever is coarser.
                let (g, j) = f.jet(x);
                if (0..2).all(|i| {
                    g[i].abs()
                        <= 4.0 * (j[i][0].abs() * w[0] + j[i][1].abs() * w[1]) + 2.0 * floor(i)
                }) {
                    push(out, &mut blurs, x, reach);
                }
            }
            continue;
        }
        let mut next = (a, b);
        if det.is_finite() && det != 0.0 {
            let y = [
                [m[1][1] / det, -m[0][1] / det],
                [-m[1][0] / det, m[0][0] / det],
            ];
            let fc = enc.f_center;
            let yi = y.map(|row| row.map(Interval::cst));
            let yf = mat_vec(yi, fc);
            // I - Y J(X).
            let one = |i: usize, j: usize| Interval::cst(if i == j { 1.0 } else { 0.0 });
            let r: [[Interval; 2]; 2] = std::array::from_fn(|i| {
                std::array::from_fn(|j| one(i, j) - (yi[i][0] * jx[0][j] + yi[i][1] * jx[1][j]))
            });
            let dx = [xb[0] - Interval::cst(c[0]), xb[1] - Interval::cst(c[1])];
            let rd = mat_vec(r, dx);
            let k: [Interval; 2] = std::array::from_fn(|i| Interval::cst(c[i]) - yf[i] + rd[i]);
            if (0..2).any(|i| k[i].hi < a[i] || k[i].lo > b[i]) {
                continue;
            }
            if (0..2).all(|i| k[i].lo > a[i] && k[i].hi < b[i]) {
                if let Some(x) = newton2(f, c, a, b) {
                    push(out, &mut blurs, x, [0.0; 2]);
                }
                continue;
            }
            let (ka, kb) = (
                [k[0].lo.max(a[0]), k[1].lo.max(a[1])],
                [k[0].hi.min(b[0]), k[1].hi.min(b[1])],
            );
            let shrunk = (0..2).all(|i| kb[i] - ka[i] <= 0.5 * (b[i] - a[i]));
            if shrunk && !stack.is_full() {
                stack.push((ka, kb));
                continue;
            }
            next = (ka, kb);
        }
        let (a, b) = next;
        if stack.len() + 2 > stack.capacity() {
            crate::budget::note_exhausted();
            return false;
        }
        // Halve across the side along which F varies more over the box (the larger "smear"
        // |J_ik| w_k, Kearfott's rule), unless a side is already at its resolution.
        let mag = |x: Interval| x.lo.abs().max(x.hi.abs());
        let smear = |k: usize| {
            let w = b[k] - a[k];
            if w <= opts.min_width[k] {
                return -1.0;
            }
            mag(jx[0][k]).max(mag(jx[1][k])) * w
        };
        let (s0, s1) = (smear(0), smear(1));
        let k = match enc.split {
            Some(k) if b[k] - a[k] > opts.min_width[k] => k,
            _ if s0 > s1 => 0,
            _ if s0 == s1
                && (b[0] - a[0]) / opts.min_width[0] >= (b[1] - a[1]) / opts.min_width[1] =>
            {
                0
            }
            _ => 1,
        };
        let mid = 0.5 * (a[k] + b[k]);
        let (mut b0, mut a1) = (b, a);
        b0[k] = mid;
        a1[k] = mid;
        stack.push((a1, b));
        stack.push((a, b0));
    }
    true
}

/// The isolator [`isolate_roots`] replaced, with the same contract: interval arithmetic
/// (second-order centred forms through nested duals of [`Interval`]s) and halving only. About
/// ten times slower; kept as the reference the faster one is tested against.
pub fn isolate_roots_reference<F: Function1D>(
    f: &F,
    lo: f64,
    hi: f64,
    opts: &IsolateOptions,
    out: &mut ArrayVec<f64, MAX_ROOTS>,
) -> bool {
    let value = |u: f64| {
        let r = f.eval(Dual::var(u));
        (r.v, r.d)
    };
    let mut stack: ArrayVec<(f64, f64), 128> = ArrayVec::new();
    stack.push((lo, hi));
    let mut evaluations = 0;
    let mut complete = true;
    while let Some((a, b)) = stack.pop() {
        evaluations += 1;
        let (fa, fb) = (value(a).0, value(b).0);
        if evaluations > opts.max_evaluations {
            // Out of budget: fall back to sign changes at the ends for what is left.
            complete = false;
            if let Some(r) = bracketed_root(&value, a, b, fa, fb) {
                let _ = push_root(out, r);
            }
            continue;
        }
        let (enclosure, slope) = enclose(f, a, b);
        if enclosure.excludes_zero() {
            continue;
        }
        if slope.excludes_zero() {
            if let Some(r) = bracketed_root(&value, a, b, fa, fb) {
                let _ = push_root(out, r);
            }
            continue;
        }
        let m = 0.5 * (a + b);
        if b - a <= opts.min_width || m <= a || m >= b || stack.len() + 2 > stack.capacity() {
            if let Some(r) = bracketed_root(&value, a, b, fa, fb) {
                let _ = push_root(out, r);
            } else if value(m).0.abs() <= opts.tangent_tolerance
                && !out.last().is_some_and(|&l| m - l <= 2.0 * opts.min_width)
            {
                let _ = push_root(out, m);
            }
            continue;
        }
        // Right half first so the left half is processed first: roots come out ascending.
        stack.push((m, b));
        stack.push((a, m));
    }
    // Roots from the budget fallback can come out of order.
    out.sort_by(f64::total_cmp);
    complete
}

/// Enclosures of `f` and `f'` over `[a, b]`: the natural interval extensions intersected with
/// the second-order centred forms (Taylor's theorem about the midpoint `m`, `h = (b - a)/2`)
/// `f(x) in f(m) + f'(m) [-h, h] + f''([a, b]) [0, h^2] / 2` and
/// `f'(x) in f'(m) + f''([a, b]) [-h, h]`, which shrink quadratically with the width where the
/// natural extensions shrink only linearly.
fn enclose<F: Function1D>(f: &F, a: f64, b: f64) -> (Interval, Interval) {
    let second = |x: Interval| {
        f.eval(Dual {
            v: Dual::var(x),
            d: Dual::cst(1.0),
        })
    };
    let whole = second(Interval::exact(a, b));
    let (nat_v, nat_d, dd) = (whole.v.v, whole.v.d, whole.d.d);
    let m = 0.5 * (a + b);
    let h = 0.5 * (b - a);
    let mid = second(Interval::cst(m));
    let (fm, dm) = (mid.v.v, mid.v.d);
    let span = Interval::new(-h, h);
    let value = fm + dm * span + dd * Interval::new(0.0, 0.5 * h * h);
    let slope = dm + dd * span;
    (meet(nat_v, value), meet(nat_d, slope))
}

/// The intersection of two enclosures of the same quantity (either one if they are disjoint,
/// which only rounding of an unbounded enclosure can cause).
fn meet(x: Interval, y: Interval) -> Interval {
    let (lo, hi) = (x.lo.max(y.lo), x.hi.min(y.hi));
    if lo <= hi { Interval::exact(lo, hi) } else { x }
}

/// Appends a root, unless it repeats the last one; returns `false` when there was no room for
/// it (more than [`MAX_ROOTS`] roots: the search is then incomplete).
fn push_root(out: &mut ArrayVec<f64, MAX_ROOTS>, r: f64) -> bool {
    // A root on a shared end point of two subintervals is found twice.
    if out
        .last()
        .is_some_and(|&l| (r - l).abs() <= 1e-14 * (1.0 + r.abs()))
    {
        return true;
    }
    out.try_push(r).is_ok()
}

/// The root of a continuous `f` in `[a, b]` when `f(a)` and `f(b)` differ in sign (or one is 0),
/// by Newton steps kept inside the shrinking bracket, bisecting when a step leaves it or
/// converges slowly. Stops at the resolution of `f64`.
pub fn bracketed_root(
    value: &impl Fn(f64) -> (f64, f64),
    a: f64,
    b: f64,
    fa: f64,
    fb: f64,
) -> Option<f64> {
    converged_root_from(value, (a, b, fa, fb), 0.5 * (a + b)).map(|(x, _)| x)
}

/// What is known of `f'` on a bracket: a first-order model
/// `f'(centre + t) in c + s t + [-rho, rho]` in `u - centre = t` (from the derivative part of
/// `f` evaluated on a [`Taylor::var`] of the bracket, [`Taylor::slope_per_unit`]) and `min`, a
/// lower bound of `|f'|` there (0 where the model does not bound it away from 0).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Slopes {
    centre: f64,
    c: f64,
    s: f64,
    rho: f64,
    min: f64,
}

impl Slopes {
    /// The model of `f'` from a [`Taylor::var`] with centre `centre` and half-width `h`.
    pub(crate) fn of(centre: f64, h: f64, model: Taylor) -> Slopes {
        let range = model.enclosure();
        let min = if range.lo > 0.0 {
            range.lo
        } else if range.hi < 0.0 {
            -range.hi
        } else {
            0.0
        };
        let (s, rho) = model.slope_per_unit(h);
        Slopes {
            centre,
            c: model.c,
            s,
            rho,
            min,
        }
    }

    /// The model's line `c + s (u - centre)` at `u`, computed in `f64`, and a bound of its
    /// rounding, `4 eps (|c| + |s (u - centre)|)` (see [`Slopes::on`]).
    #[inline]
    fn line(self, u: f64) -> (f64, f64) {
        let k = self.s * (u - self.centre);
        (self.c + k, 4.0 * f64::EPSILON * (self.c.abs() + k.abs()))
    }

    /// The same model on `[a, b]`, part of its domain, with `min` bounded there: the line
    /// `c + s (u - centre)` takes its extremes over `[a, b]` at the ends, so where it stays
    /// beyond `rho` of 0 at both, with one sign, `|f'| >= min(|line(a)|, |line(b)|) - rho`;
    /// otherwise `min = 0`. Each end's line value is computed in `f64` and moved away from 0
    /// by `4 eps (|c| + |s (u - centre)|)`: its three roundings take at most `1.5 eps` of that
    /// sum, and the move's own rounding `0.5 eps` more. Taking `rho` away rounds by half an ulp
    /// of the result, which `1 - eps` takes back (`rho`, rounded up by
    /// [`Taylor::slope_per_unit`], is at least the least subnormal, twice any rounding among
    /// subnormals). Non-finite parts give `min = 0`.
    #[inline]
    pub(crate) fn on(self, a: f64, b: f64) -> Slopes {
        let ((la, ea), (lb, eb)) = (self.line(a), self.line(b));
        // NaN or infinite parts bound nothing.
        if !(la + lb + ea + eb + self.rho).is_finite() {
            return Slopes { min: 0.0, ..self };
        }
        let lo = fmin(la - ea, lb - eb) - self.rho;
        let hi = fmax(la + ea, lb + eb) + self.rho;
        let min = if lo > 0.0 {
            lo * (1.0 - f64::EPSILON)
        } else if hi < 0.0 {
            -hi * (1.0 - f64::EPSILON)
        } else {
            0.0
        };
        Slopes { min, ..self }
    }

    /// Whether `f < 0` on `[a, b]`, part of the model's domain, given `f(a) < 0` and `f(b) < 0`
    /// (the middle of a U). Where the model proves `f` monotone there, `f` lies between those
    /// values. Otherwise, with `x1`, `x2` where the line is `-2 rho` and `2 rho` (its zero `z`
    /// between them), the line's values (moved by their rounding, as in [`Slopes::on`]) must
    /// show `f' < 0` on `[a, x1]` and `f' > 0` on `[x2, b]`: then `f <= f(a)` on `[a, x1]` and
    /// `f <= f(b)` on `[x2, b]`, and between them too. On `[x1, z]`, with `v = u - z`,
    /// `f(u) - f(x1) <= int (line + rho) = v (s v / 2 + rho) <= 0` (`-2 rho / s <= v <= 0`);
    /// on `[z, x2]`, `f(u) - f(x2) <= -int_u^x2 (line - rho) = -v (rho - s v / 2) <= 0`. So
    /// `f <= max(f(a), f(b)) < 0`. The values at `a` and `b` are taken as computed, as the
    /// signs at cells' ends are everywhere.
    pub(crate) fn keeps_negative(self, (a, b, fa, fb): Cell) -> bool {
        if !(fa < 0.0 && fb < 0.0) {
            return false;
        }
        // Monotone: between its ends' values.
        if self.on(a, b).min > 0.0 {
            return true;
        }
        if !(self.s > 0.0) {
            return false;
        }
        let x1 = self.centre + (-2.0 * self.rho - self.c) / self.s;
        let x2 = self.centre + (2.0 * self.rho - self.c) / self.s;
        if !(a < x1 && x1 <= x2 && x2 < b) {
            return false;
        }
        let [(la, ea), (l1, e1), (l2, e2), (lb, eb)] = [a, x1, x2, b].map(|u| self.line(u));
        let falling = fmax(la + ea, l1 + e1) + self.rho;
        let rising = fmin(l2 - e2, lb - eb) - self.rho;
        // NaN fails both comparisons.
        falling < 0.0 && rising > 0.0
    }
}

/// [`bracketed_root`] with the first iterate `x0` (the midpoint if `x0` is not inside) and what
/// is known of `f'` there.
///
/// Where `|f'| >= min > 0` on the bracket, an iterate is a root to within `eps |x|` (as a bracket
/// closed to `2 eps max(|a|, |b|)` gives its end with the smaller residual) without closing
/// the bracket about it. By the mean value theorem the root `r` has
/// `|f(x)| = |f(x) - f(r)| >= min |x - r|`, so:
/// - `|f(x)| <= min eps |x|` gives `|x - r| <= eps |x|`;
/// - Newton's next iterate `y = x - f(x) / g` (`g` the computed `f'(x)`, whatever its error)
///   has `f(y) = f(x) - (x - y) f'(xi)` for a `xi` between them, so
///   `|f(y)| = |x - y| |g - f'(xi)| <= |x - y| V` with
///   `V = |g - (c + s (x - centre))| + |s| |x - y| + rho` from the model (`f'(xi)` is within
///   `rho` of the model's line, whose rounding `rho` covers too); where
///   `|x - y| (V + eps |g|) <= min eps |y| / 2` (the second term covers the step's
///   rounding), `y` rounded to `f64` is within `eps |y|` of `r`, and is returned without
///   evaluating `f` there.
///
/// Near a simple root, Newton's iterates pass the second test one or two evaluations before
/// the bracket would close. Like closing the bracket, both take the computed `f` as exact at
/// the iterates (its rounding moves the answer by what it moves the sign changes).
///
/// Since the second test holds for any `g`, an iterate whose test the last step predicts to
/// pass is evaluated by `point` (`f` alone, cheaper than `f` and `f'` together) and stepped
/// with the last `g`. The prediction: Newton's error after a step `delta` is about
/// `f'' delta^2 / (2 f')`, with the model's slope `s` for `f''`; where the next step, taken at
/// twice that, would pass the test with the same `V`, the next evaluation is `point`'s. A
/// wrong prediction costs nothing but speed: the test is made as always, and the iteration
/// goes on with full evaluations. (On the elliptical fibers' Radial roots Newton's method
/// takes three evaluations from the isolation's estimates, steps of about `1e-5`, `1e-9` and
/// `1e-16`: the last needs no `f'`.)
pub(crate) fn bracketed_root_from(
    value: &impl Fn(f64) -> (f64, f64),
    point: &impl Fn(f64) -> f64,
    (a, b, fa, fb): Cell,
    x0: f64,
    slopes: Slopes,
) -> Option<f64> {
    newton_in_bracket(value, point, (a, b, fa, fb), x0, Some(slopes)).map(|(x, _)| x)
}

/// [`bracketed_root`] from `x0`, and whether the bracket closed to the resolution of `f64` (or
/// hit an exact zero): `false` when the iteration cap was reached first, and the end returned
/// (the one with the smaller residual) need not be near a root.
pub(crate) fn converged_root_from(
    value: &impl Fn(f64) -> (f64, f64),
    (a, b, fa, fb): Cell,
    x0: f64,
) -> Option<(f64, bool)> {
    newton_in_bracket(value, &|x| value(x).0, (a, b, fa, fb), x0, None)
}

/// Newton's method in the bracket, as [`bracketed_root_from`] and [`converged_root_from`] (one
/// copy for each, so that the second's has no slope tests).
#[inline(always)]
fn newton_in_bracket(
    value: &impl Fn(f64) -> (f64, f64),
    point: &impl Fn(f64) -> f64,
    (a, b, fa, fb): Cell,
    x0: f64,
    slopes: Option<Slopes>,
) -> Option<(f64, bool)> {
    if fa == 0.0 {
        return Some((a, true));
    }
    if fb == 0.0 {
        return Some((b, true));
    }
    if !(fa.signum() != fb.signum()) {
        return None;
    }
    let (mut a, mut b, mut fa, mut fb) = (a, b, fa, fb);
    let rising = fb > 0.0;
    let mut x = if x0 > a && x0 < b { x0 } else { 0.5 * (a + b) };
    let mut last_width = b - a;
    let mut converged = false;
    let min_slope = slopes.map_or(0.0, |s| s.min);
    // The last `g`, where the next iterate's test is predicted to pass with it.
    let mut kept_slope: Option<f64> = None;
    for _ in 0..200 {
        let (fx, dfx) = match kept_slope.take() {
            Some(g) => (point(x), g),
            None => value(x),
        };
        if !fx.is_finite() {
            return None;
        }
        // An exact zero, or a root within `eps |x|` by the slope bound.
        if fx.abs() <= min_slope * (f64::EPSILON * x.abs()) {
            return Some((x, true));
        }
        if (fx > 0.0) == rising {
            (b, fb) = (x, fx);
        } else {
            (a, fa) = (x, fx);
        }
        let width = b - a;
        if width <= 2.0 * f64::EPSILON * a.abs().max(b.abs()).max(1e-300) {
            converged = true;
            break;
        }
        let step = fx / dfx;
        let mut newton = x - step;
        let mut predicted = false;
        if let Some(Slopes {
            centre,
            c,
            s,
            rho,
            min,
        }) = slopes
            && min > 0.0
            && newton > a
            && newton < b
        {
            let change = (dfx - (c + s * (x - centre))).abs()
                + s.abs() * step.abs()
                + rho
                + f64::EPSILON * dfx.abs();
            if step.abs() * change <= 0.5 * min * (f64::EPSILON * newton.abs()) {
                return Some((newton, true));
            }
            let next = (s * step * step / dfx).abs();
            predicted = next * change <= 0.5 * min * (f64::EPSILON * newton.abs());
        }
        // Newton's iterates converge from one side, and the far end of the bracket stays put:
        // once the step is below an ulp, step one ulp across the root to close the bracket.
        if (newton - x).abs() <= f64::EPSILON * x.abs() {
            newton = if step > 0.0 {
                x.next_down()
            } else {
                x.next_up()
            };
        }
        // Newton's step when it stays in the bracket and either the bracket shrinks fast or the
        // step is small; otherwise bisect.
        let inside = newton > a && newton < b;
        x = if inside && (width < 0.7 * last_width || (newton - x).abs() < 0.25 * width) {
            if predicted {
                kept_slope = Some(dfx);
            }
            newton
        } else {
            0.5 * (a + b)
        };
        last_width = width;
        if x <= a || x >= b {
            // The midpoint of a bracket with no float inside.
            converged = true;
            break;
        }
    }
    // The end with the smaller residual.
    Some((if fa.abs() <= fb.abs() { a } else { b }, converged))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quadratic_roots_are_accurate_without_cancellation() {
        // x^2 - 1e8 x + 1: roots ~1e8 and ~1e-8; the naive formula loses the small one.
        let r = quadratic_roots(1.0, -1e8, 1.0);
        assert_eq!(r.len(), 2, "two roots");
        assert!((r[0] - 1e-8).abs() < 1e-22, "small root {}", r[0]);
        assert!((r[1] - 1e8).abs() < 1e-6, "large root {}", r[1]);
        assert_eq!(quadratic_roots(1.0, 0.0, 1.0).len(), 0, "complex roots");
        assert_eq!(quadratic_roots(0.0, 2.0, -1.0).as_slice(), &[0.5], "linear");
        assert_eq!(
            quadratic_roots(1.0, -2.0, 1.0).as_slice(),
            &[1.0],
            "double root once"
        );
    }

    /// The bracketed solver says whether its bracket closed: it does for a smooth function
    /// (the root to an ulp), and not when a wrong slope keeps it crawling by ulps until the
    /// iteration cap, where the end it returns is far from the root.
    #[test]
    fn bracketed_root_reports_convergence() {
        let f = |x: f64| x * x - 2.0;
        let (r, converged) =
            converged_root_from(&|x: f64| (f(x), 2.0 * x), (0.0, 2.0, f(0.0), f(2.0)), 1.0)
                .unwrap();
        assert!(converged, "a smooth root converges");
        assert!((r - 2f64.sqrt()).abs() <= 4.0 * f64::EPSILON, "root {r}");
        // An infinite slope: every Newton step is zero, so the iterate creeps by an ulp.
        let (r, converged) = converged_root_from(
            &|x: f64| (f(x), f64::INFINITY),
            (0.0, 2.0, f(0.0), f(2.0)),
            1.0,
        )
        .unwrap();
        assert!(!converged, "the cap was reached: {r}");
        assert!(
            (r - 2f64.sqrt()).abs() > 0.1,
            "the end returned is not the root: {r}"
        );
    }

    /// Newton's method with a slope model stops where the model proves an iterate, or the next
    /// one, within `eps |x|` of the root. Brackets 1e-9 to 0.3 wide about the roots of
    /// `x^2 - 2`, `sin x - 1/2` and `d + 300 d^2 / (1 + (d / 1e-3)^2)` with `d = x - 1/3` (its
    /// curvature concentrated within 1e-3 of the root, where steps that merely shrink misjudge
    /// it), from random starts in them (those the model proves monotone, most of them): the
    /// root is within `eps |r|` of the true one (plus, for
    /// the first two, an ulp for their rounding near the root and the reference's), and found
    /// with no more evaluations than closing the bracket takes (fewer on average), an
    /// evaluation of `f` alone counted as one. More than one bracket in two takes such an
    /// evaluation at an iterate the last step predicted to pass (with `f` halved there, this
    /// test and `grazing_minima_are_ruled_out_and_dips_kept` fail).
    #[test]
    fn slope_models_stop_newton_at_a_proven_root() {
        use std::cell::Cell;
        const THIRD: f64 = 1.0 / 3.0;
        struct Square;
        impl Function1D for Square {
            fn eval<T: Real>(&self, x: T) -> T {
                x * x - T::cst(2.0)
            }
        }
        struct Sine;
        impl Function1D for Sine {
            fn eval<T: Real>(&self, x: T) -> T {
                x.sin() - T::cst(0.5)
            }
        }
        struct Curved;
        impl Function1D for Curved {
            fn eval<T: Real>(&self, x: T) -> T {
                let d = x - T::cst(THIRD);
                let q = d.scale(1e3);
                d + (d * d).scale(300.0) / (T::cst(1.0) + q * q)
            }
        }
        fn run<F: Function1D>(
            f: &F,
            root: f64,
            slack_ulps: f64,
            rng: &mut u64,
        ) -> (u32, u32, u32, u32) {
            let ulp = root.next_up() - root;
            let tolerance = f64::EPSILON * root.abs() + slack_ulps * ulp;
            let mut next = || {
                *rng ^= *rng << 13;
                *rng ^= *rng >> 7;
                *rng ^= *rng << 17;
                (*rng >> 11) as f64 / (1u64 << 53) as f64
            };
            let (mut with, mut without, mut cases) = (0, 0, 0);
            // Evaluations of `f` alone, with the last step's `f'`.
            let points = Cell::new(0);
            for _ in 0..2000 {
                let width = 10f64.powf(-9.0 + 8.5 * next());
                let a = root - (0.02 + 0.96 * next()) * width;
                let b = a + width;
                let start = a + next() * width;
                let var = Taylor::var(a, b);
                let Dual { d: slope, .. } = f.eval(Dual::var(var));
                let slopes = Slopes::of(var.c, var.s, slope);
                if slopes.min == 0.0 {
                    // Not proven monotone by the model (the isolator splits such cells).
                    continue;
                }
                let calls = Cell::new(0);
                let value = |x: f64| {
                    calls.set(calls.get() + 1);
                    let r = f.eval(Dual::var(x));
                    (r.v, r.d)
                };
                // `f` alone counts as an evaluation too.
                let point = |x: f64| {
                    calls.set(calls.get() + 1);
                    points.set(points.get() + 1);
                    f.eval(x)
                };
                let (fa, fb) = (f.eval(a), f.eval(b));
                let r = bracketed_root_from(&value, &point, (a, b, fa, fb), start, slopes).unwrap();
                let proven = calls.replace(0);
                assert!(
                    (r - root).abs() <= tolerance,
                    "root {r} against {root} ({} ulps) on [{a}, {b}] from {start}",
                    (r - root) / ulp
                );
                let (closed, converged) =
                    converged_root_from(&value, (a, b, fa, fb), start).unwrap();
                assert!(
                    converged && (closed - root).abs() <= tolerance,
                    "closed {closed}"
                );
                let closing = calls.get();
                assert!(
                    proven <= closing,
                    "{proven} evaluations against {closing} on [{a}, {b}] from {start}"
                );
                with += proven;
                without += closing;
                cases += 1;
            }
            (with, without, cases, points.get())
        }
        let mut rng = 0x9e37_79b9_7f4a_7c15u64;
        for (name, (with, without, cases, points)) in [
            (
                "square",
                run(&Square, std::f64::consts::SQRT_2, 1.0, &mut rng),
            ),
            (
                "sine",
                run(&Sine, std::f64::consts::FRAC_PI_6, 1.0, &mut rng),
            ),
            ("curved", run(&Curved, THIRD, 0.0, &mut rng)),
        ] {
            eprintln!(
                "{name}: {with} evaluations ({points} of f alone) against {without} in {cases} brackets"
            );
            // The last step's `f'` serves most final iterates.
            assert!(
                points * 2 > cases,
                "{name}: {points} evaluations of f alone in {cases} brackets"
            );
            assert!(
                with < without,
                "{name}: {with} evaluations against {without}"
            );
        }
    }

    /// The slope model's remainder bounds how much `f'` may change within a Newton step:
    /// `f(x) = x - k + sin(1e6 x) / 2e6` has the model `f' in 1 + [-1/2, 1/2]` over a cell
    /// 2e-3 wide (constant centre and slope, the wiggle all in `rho`), and from a start at a
    /// crest of the sine (`f' = 1` there, `f''` = 5e5) 1e-10 above the root, a stop that left
    /// `rho` out would take the first Newton step as final, 11 `eps |r|` off (the review's
    /// case). The root against plain bisection of `f`'s sign to adjacent floats.
    #[test]
    fn the_slope_remainder_bounds_the_step() {
        struct Wiggly(f64);
        impl Function1D for Wiggly {
            fn eval<T: Real>(&self, x: T) -> T {
                x - T::cst(self.0) + x.scale(1e6).sin().scale(0.5e-6)
            }
        }
        let pi = std::f64::consts::PI;
        let x0 = (0.5 * pi + (1e6 / pi).round() * pi) / 1e6;
        let f = Wiggly(x0 + 0.5e-6 * (1e6 * x0).sin() - 1e-10);
        let (a, b) = (x0 - 1e-3, x0 + 1e-3);
        let (fa, fb) = (f.eval(a), f.eval(b));
        let var = Taylor::var(a, b);
        let Dual { d: slope, .. } = f.eval(Dual::var(var));
        let slopes = Slopes::of(var.c, var.s, slope);
        assert!(slopes.min >= 0.49 && slope.rho >= 0.49, "{slopes:?}");
        let value = |x: f64| {
            let r = f.eval(Dual::var(x));
            (r.v, r.d)
        };
        let point = |x: f64| f.eval(x);
        let r = bracketed_root_from(&value, &point, (a, b, fa, fb), x0, slopes).unwrap();
        // Bisection: `f(lo) < 0 < f(hi)`, to adjacent floats.
        let (mut lo, mut hi) = (a, b);
        while lo.next_up() < hi {
            let m = 0.5 * (lo + hi);
            if f.eval(m) < 0.0 { lo = m } else { hi = m }
        }
        let tolerance = f64::EPSILON * r.abs() + (hi - lo);
        assert!(
            (r - lo).abs() <= tolerance || (r - hi).abs() <= tolerance,
            "root {r}, sign change in [{lo}, {hi}] ({} eps)",
            (r - lo) / (f64::EPSILON * r)
        );
    }

    struct Wiggle;
    impl Function1D for Wiggle {
        /// sin(40 u) - 0.3 + 0.2 u: 13 roots in [0, 1] (checked by dense sign sampling below).
        fn eval<T: Real>(&self, u: T) -> T {
            u.scale(40.0).sin() - T::cst(0.3) + u.scale(0.2)
        }
    }

    #[test]
    fn isolate_finds_every_sign_change_of_a_wiggly_function() {
        let mut out = ArrayVec::new();
        assert!(
            isolate_roots(&Wiggle, 0.0, 1.0, &IsolateOptions::default(), &mut out),
            "budget"
        );
        let f = |u: f64| (40.0 * u).sin() - 0.3 + 0.2 * u;
        let n = 200_000;
        let changes = (0..n)
            .filter(|&i| f(i as f64 / n as f64).signum() != f((i + 1) as f64 / n as f64).signum())
            .count();
        assert_eq!(out.len(), changes, "roots {out:?}");
        for w in out.windows(2) {
            assert!(w[0] < w[1], "ascending");
        }
        for &r in &out {
            assert!(f(r).abs() < 1e-14, "residual {} at {r}", f(r));
        }
    }

    struct Tangent;
    impl Function1D for Tangent {
        /// (u - 0.3)^2: a double root that no sign test sees.
        fn eval<T: Real>(&self, u: T) -> T {
            (u - T::cst(0.3)).sqr()
        }
    }

    #[test]
    fn isolate_reports_a_tangential_root_once() {
        let mut out = ArrayVec::new();
        isolate_roots(&Tangent, 0.0, 1.0, &IsolateOptions::default(), &mut out);
        assert_eq!(out.len(), 1, "double root {out:?}");
        assert!((out[0] - 0.3).abs() < 1e-9, "at 0.3: {}", out[0]);
    }

    /// `prod (u - r_i)` times a positive wobble, with known roots.
    struct Product {
        roots: Vec<f64>,
    }
    impl Function1D for Product {
        fn eval<T: Real>(&self, u: T) -> T {
            let wobble = T::cst(1.5) + (u.scale(7.0)).sin().scale(0.5);
            self.roots
                .iter()
                .fold(wobble, |acc, &r| acc * (u - T::cst(r)))
        }
    }

    /// Both lists are `roots`, each root to 1e-13.
    fn assert_both_find(a: &[f64], b: &[f64], roots: &[f64], case: usize) {
        assert_eq!(a.len(), roots.len(), "case {case}: {roots:?}: {a:?}");
        assert_eq!(b.len(), roots.len(), "case {case}: {roots:?}: {b:?}");
        for ((x, y), r) in a.iter().zip(b).zip(roots) {
            assert!(
                (x - r).abs() < 1e-13 && (y - r).abs() < 1e-13,
                "case {case}: {x} {y} {r}"
            );
        }
    }

    /// A function that counts its enclosures (evaluations over intervals): of itself and its
    /// derivative together (`Dual<Taylor>`: one a cell the isolator examines, but for the cells
    /// that its value's enclosure alone rules out), and of itself alone (`Taylor`). (The types
    /// are told apart by name: `Real` has no `'static` bound for `TypeId`.)
    struct Counted<'a, F> {
        f: &'a F,
        enclosures: std::cell::Cell<usize>,
        values: std::cell::Cell<usize>,
    }
    impl<'a, F> Counted<'a, F> {
        fn new(f: &'a F) -> Self {
            Counted {
                f,
                enclosures: std::cell::Cell::new(0),
                values: std::cell::Cell::new(0),
            }
        }
    }
    impl<F: Function1D> Function1D for Counted<'_, F> {
        fn eval<T: Real>(&self, u: T) -> T {
            let count = if std::any::type_name::<T>() == std::any::type_name::<Taylor>() {
                &self.values
            } else if T::ENCLOSURE {
                &self.enclosures
            } else {
                return self.f.eval(u);
            };
            count.set(count.get() + 1);
            self.f.eval(u)
        }
    }

    /// `slope_bound` bounds the rise of `f` from `y` below: for cubics with a wobble (whose
    /// derivatives the models enclose, not reproduce), cells from 1e-9 to 1 wide, `y` at the
    /// model's critical point or anywhere in the cell, `f(x) - f(y)` at 65 points of the cell is
    /// never below it (less `f64`'s rounding of the two samples); and about the minimum of a
    /// convex cell below 1e-2 wide, `f(y)` plus the bound is above the value model's lower
    /// bound, often (the bound is of fourth order in the width there, `-rho'^2 / 2s'`).
    #[test]
    fn slope_bound_bounds_the_rise_from_a_point() {
        struct Cubic([f64; 4]);
        impl Function1D for Cubic {
            fn eval<T: Real>(&self, u: T) -> T {
                let k = self.0;
                let wobble = (u.scale(3.0)).sin().scale(1e-3);
                T::cst(k[0]) + u * (T::cst(k[1]) + u * (T::cst(k[2]) + u.scale(k[3]))) + wobble
            }
        }
        let mut rng = crate::test_rng::Lcg(97);
        let (mut checked, mut tighter) = (0, 0);
        for case in 0..3000 {
            let k: [f64; 4] = std::array::from_fn(|_| rng.range(-2.0, 2.0));
            let f = Cubic(k);
            let width = 10f64.powf(rng.range(-9.0, 0.0));
            // Half the cells about a critical point of the cubic (3 k3 x^2 + 2 k2 x + k1 = 0),
            // where there is one.
            let disc = k[2] * k[2] - 3.0 * k[3] * k[1];
            let centre = if case % 2 == 0 && disc > 0.0 {
                (-k[2] + disc.sqrt()) / (3.0 * k[3]) + rng.range(-0.2, 0.2) * width
            } else {
                rng.range(-1.0, 1.0)
            };
            let a = centre - 0.5 * width;
            let b = centre + 0.5 * width;
            let var = Taylor::var(a, b);
            let Dual { v: model, d: slope } = f.eval(Dual::var(var));
            let (m, h) = (var.c, var.s);
            let critical = m - h * (slope.c / slope.s);
            let y = if case % 2 == 0 && a < critical && critical < b {
                critical
            } else {
                rng.range(a, b)
            };
            let bound = slope_bound(slope, (m, h), y, (a, b));
            let fy = f.eval(y);
            for j in 0..=64 {
                let x = a + (b - a) * j as f64 / 64.0;
                let fx = f.eval(x);
                let slack = 1e-15 * (fx.abs() + fy.abs() + 1.0);
                assert!(
                    fx - fy >= bound - slack,
                    "case {case}: f({x}) - f({y}) = {} below {bound}",
                    fx - fy
                );
                checked += 1;
            }
            let lowest = model.enclosure().lo;
            if y == critical && slope.s > 0.0 && width < 1e-2 && fy + bound > lowest {
                tighter += 1;
            }
        }
        assert!(
            checked > 190_000 && tighter > 100,
            "{checked} samples, {tighter} tighter"
        );
    }

    /// `Slopes::on` bounds `|f'|` below on part of the model's domain: for cubics with a wobble
    /// of up to a tenth of their size (whose slopes the model encloses with a remainder, not
    /// reproduces), models over cells 1e-9 to 1 wide and parts of them from the whole cell to a
    /// millionth of it, `|f'|` (the analytic derivative) at 65 points of the part is never
    /// below `min`, less `f64`'s rounding of the samples. And the bound is not vacuous: it is
    /// positive on most parts where `f'` keeps away from zero.
    #[test]
    fn slopes_on_a_part_bound_the_slope_there() {
        struct Wobbly {
            k: [f64; 4],
            wobble: f64,
        }
        impl Wobbly {
            /// `f'(u) = k1 + 2 k2 u + 3 k3 u^2 + 7 w cos(7 u)`.
            fn slope(&self, u: f64) -> f64 {
                let k = self.k;
                k[1] + u * (2.0 * k[2] + 3.0 * k[3] * u) + 7.0 * self.wobble * (7.0 * u).cos()
            }
        }
        impl Function1D for Wobbly {
            fn eval<T: Real>(&self, u: T) -> T {
                let k = self.k;
                let wobble = (u.scale(7.0)).sin().scale(self.wobble);
                T::cst(k[0]) + u * (T::cst(k[1]) + u * (T::cst(k[2]) + u.scale(k[3]))) + wobble
            }
        }
        let mut rng = crate::test_rng::Lcg(113);
        let (mut away, mut proved, mut checked) = (0, 0, 0);
        for case in 0..4000 {
            let k: [f64; 4] = std::array::from_fn(|_| rng.range(-2.0, 2.0));
            let f = Wobbly {
                k,
                wobble: rng.range(0.0, 0.1),
            };
            let width = 10f64.powf(rng.range(-9.0, 0.0));
            let lo = rng.range(-1.0, 1.0);
            let hi = lo + width;
            let var = Taylor::var(lo, hi);
            let Dual { d: slope, .. } = f.eval(Dual::var(var));
            let whole = Slopes::of(var.c, var.s, slope);
            let part = width * 10f64.powf(rng.range(-6.0, 0.0));
            let a = rng.range(lo, hi - part);
            let b = if case % 4 == 0 { hi } else { a + part };
            let min = whole.on(a, b).min;
            assert!(min >= 0.0, "case {case}: {min}");
            let mut least = f64::INFINITY;
            for j in 0..=64 {
                let x = a + (b - a) * j as f64 / 64.0;
                let d = f.slope(x);
                let slack = 1e-14 * (k.iter().map(|c| c.abs()).sum::<f64>() + 1.0);
                assert!(
                    d.abs() + slack >= min,
                    "case {case}: |f'({x})| = {} below {min} on [{a}, {b}] of [{lo}, {hi}]",
                    d.abs()
                );
                least = least.min(d.abs());
                checked += 1;
            }
            // Where |f'| stays above a tenth of the model's reach (its slope across the cell
            // and remainder), the part should be proved monotone.
            let reach = (slope.s.abs() + slope.rho) / var.s * width;
            if least > 0.1 * reach + 1e-9 {
                away += 1;
                proved += usize::from(min > 0.0);
            }
        }
        assert!(checked > 250_000, "{checked} samples");
        assert!(
            away > 1000 && 10 * proved >= 9 * away,
            "{proved} of {away} parts away from f' = 0 proved monotone"
        );
    }

    /// `Slopes::keeps_negative` rules out the middle of a U only where `f < 0` throughout it:
    /// U's `(u - r0) (u - r1) (1 + k u)` with a ripple `A sin(w u)` (from none to one that
    /// lifts the bottom above zero in places, `w` from 5 to 200) or a narrow bump at the
    /// bottom that rises above zero (which only the bound across the zero of `f'` sees), models over an interval 1.1 to 2
    /// times the roots' gap about them, middles of a hundredth of the gap to nearly all of it,
    /// both ends negative: wherever it says so, `f` sampled at 201 points of the middle is
    /// negative; and it says so for most middles of the smooth U's placed as a U's cuts place
    /// them (about the bottom, a third to a half of the gap wide).
    #[test]
    fn middles_kept_negative_are_negative() {
        struct Rippled {
            roots: [f64; 2],
            k: f64,
            amp: f64,
            freq: f64,
            /// A bump `height / (1 + ((u - at) / width)^2)`.
            bump: [f64; 3],
        }
        impl Function1D for Rippled {
            fn eval<T: Real>(&self, u: T) -> T {
                let [r0, r1] = self.roots;
                let ripple = u.scale(self.freq).sin().scale(self.amp);
                let u_shape =
                    (u - T::cst(r0)) * (u - T::cst(r1)) * (T::cst(1.0) + u.scale(self.k)) + ripple;
                let [height, at, width] = self.bump;
                if height == 0.0 {
                    return u_shape;
                }
                let z = (u - T::cst(at)).scale(1.0 / width);
                u_shape + T::cst(height) / (T::cst(1.0) + z.sqr())
            }
        }
        let mut rng = crate::test_rng::Lcg(131);
        let (mut smooth, mut smooth_kept, mut kept, mut checked) = (0, 0, 0, 0);
        for case in 0..3000 {
            let (r0, r1) = (rng.range(0.05, 0.45), rng.range(0.55, 0.95));
            let depth = 0.25 * (r1 - r0) * (r1 - r0);
            let (amp, bump) = match case % 4 {
                0 => (0.0, 0.0),
                1 => (depth * 10f64.powf(rng.range(-4.0, -1.0)), 0.0),
                2 => (depth * rng.range(0.5, 2.0), 0.0),
                _ => (0.0, depth * rng.range(1.1, 3.0)),
            };
            let gap = r1 - r0;
            let f = Rippled {
                roots: [r0, r1],
                k: rng.range(-0.1, 0.1),
                amp,
                freq: 10f64.powf(rng.range(0.7, 2.3)),
                bump: [
                    bump,
                    0.5 * (r0 + r1) + rng.range(-0.1, 0.1) * gap,
                    gap * 10f64.powf(rng.range(-2.3, -1.0)),
                ],
            };
            // The U's interval reaches a little beyond its roots (as a tube's window does).
            let (lo, hi) = (
                r0 - rng.range(0.05, 0.5) * gap,
                r1 + rng.range(0.05, 0.5) * gap,
            );
            let var = Taylor::var(lo, hi);
            let Dual { d: slope, .. } = f.eval(Dual::var(var));
            let slopes = Slopes::of(var.c, var.s, slope);
            let width = if case % 2 == 0 {
                gap * rng.range(0.3, 0.6)
            } else {
                gap * 10f64.powf(rng.range(-2.0, -0.1))
            };
            // Half about the bottom (where a U's middle is cut), half anywhere between the roots.
            let spread = if case % 2 == 0 { 0.05 } else { 0.3 };
            let mid = 0.5 * (r0 + r1) + rng.range(-spread, spread) * gap;
            let (a, b) = (mid - 0.5 * width, mid + 0.5 * width);
            let (fa, fb) = (f.eval(a), f.eval(b));
            if !(fa < 0.0 && fb < 0.0 && a > lo && b < hi) {
                continue;
            }
            let says = slopes.keeps_negative((a, b, fa, fb));
            // A smooth U's middle as its cuts place it: about the bottom, a third to a half of
            // the gap.
            if amp == 0.0 && bump == 0.0 && case % 2 == 0 {
                smooth += 1;
                smooth_kept += usize::from(says);
            }
            if says {
                kept += 1;
                for j in 0..=200 {
                    let x = a + (b - a) * j as f64 / 200.0;
                    assert!(
                        f.eval(x) < 0.0,
                        "case {case}: f({x}) = {} on [{a}, {b}], kept negative",
                        f.eval(x)
                    );
                    checked += 1;
                }
            }
        }
        assert!(
            smooth > 200 && 10 * smooth_kept >= 9 * smooth,
            "{smooth_kept} of {smooth} smooth middles kept"
        );
        assert!(
            kept > 800 && checked > 160_000,
            "{kept} kept, {checked} samples"
        );
    }

    /// `Slopes::keeps_negative` against the highest function its model allows: where `f'` lies
    /// in `c + s (u - centre) + [-rho, rho]` and `f(a)`, `f(b)` are given, `f(u)` is at most
    /// `min(f(a) + int_a^u (line + rho), f(b) - int_u^b (line - rho))`, and some such `f`
    /// reaches it. For random models and cells (about the line's zero, just beyond the zone
    /// where it is within `2 rho` of zero, or anywhere; ends from far below zero to just below
    /// it), wherever the method says `f < 0`, that highest value,
    /// sampled at 401 points, is negative; and it says so for some cells in every family.
    #[test]
    fn keeps_negative_holds_for_the_worst_slopes_the_model_allows() {
        let mut rng = crate::test_rng::Lcg(137);
        let (mut said, mut about_zero) = (0, 0);
        for case in 0..20_000 {
            let centre = rng.range(-1.0, 1.0);
            let s = 10f64.powf(rng.range(-2.0, 2.0));
            let c = s * rng.range(-0.5, 0.5);
            let rho = s * 10f64.powf(rng.range(-6.0, -0.5));
            let slopes = Slopes {
                centre,
                c,
                s,
                rho,
                min: 0.0,
            };
            let zero = centre - c / s;
            let zone = 2.0 * rho / s;
            let (a, b) = match case % 3 {
                0 => (zero - rng.range(0.0, 0.5), zero + rng.range(0.0, 0.5)),
                // Just beyond the zone where the line is within `2 rho` of zero.
                1 => (
                    zero - zone * rng.range(1.0, 1.5),
                    zero + zone * rng.range(1.0, 1.5),
                ),
                _ => {
                    let a = rng.range(centre - 1.0, centre + 1.0);
                    (a, a + rng.range(1e-6, 0.5))
                }
            };
            let scale = s * (b - a) * (b - a);
            let fa = -scale * 10f64.powf(rng.range(-8.0, 0.0));
            let fb = -scale * 10f64.powf(rng.range(-8.0, 0.0));
            if !slopes.keeps_negative((a, b, fa, fb)) {
                continue;
            }
            said += 1;
            about_zero += usize::from(a < zero && zero < b);
            let integral = |x: f64, y: f64, k: f64| {
                c * (y - x) + 0.5 * s * ((y - centre).powi(2) - (x - centre).powi(2)) + k * (y - x)
            };
            for j in 0..=400 {
                let u = a + (b - a) * j as f64 / 400.0;
                let highest = (fa + integral(a, u, rho)).min(fb - integral(u, b, -rho));
                let slack = 1e-12 * (fa.abs() + fb.abs() + scale);
                assert!(
                    highest < slack,
                    "case {case}: f can reach {highest} at {u} in [{a}, {b}] ({fa}, {fb}), {slopes:?}"
                );
            }
        }
        assert!(
            said > 2000 && about_zero > 1000,
            "{said} kept negative, {about_zero} about the line's zero"
        );
    }

    /// On a U-shaped interval ([`u_shaped_cells`] cuts it into the entry's side, a middle and
    /// the exit's side), one model of `f'` over the whole interval proves both sides monotone:
    /// U's close to a parabola (as `g` is across a fiber: a bend `1 + k u`, `|k| <= 0.03`, and a
    /// wobble of at most 0.003) with two roots (far apart; near the ends; 2e-9 to 0.2 apart in a
    /// window 1.5 to 4 times as wide) mostly (540 of 600) take that one pair of models (which
    /// rules out the middle too, [`Slopes::keeps_negative`]), and find both roots to 1e-13. A
    /// W (a side with three roots, where no model can prove that side monotone) and a U whose
    /// side holds a wiggle still give every root: the sides fall back to their own models.
    #[test]
    fn one_slope_model_takes_both_sides_of_a_u() {
        /// `(u - r0) (u - r1) (1 + k u + w sin(5 u))`.
        struct Gentle {
            roots: [f64; 2],
            k: f64,
            w: f64,
        }
        impl Function1D for Gentle {
            fn eval<T: Real>(&self, u: T) -> T {
                let [r0, r1] = self.roots;
                let bend = T::cst(1.0) + u.scale(self.k) + u.scale(5.0).sin().scale(self.w);
                (u - T::cst(r0)) * (u - T::cst(r1)) * bend
            }
        }
        let mut rng = crate::test_rng::Lcg(59);
        let shaped = IsolateOptions {
            u_shaped: true,
            ..IsolateOptions::default()
        };
        let mut one_pair = 0;
        for case in 0..600 {
            // Roots, and the interval about them.
            let (roots, lo, hi) = match case % 3 {
                0 => (vec![rng.range(0.05, 0.45), rng.range(0.55, 0.95)], 0.0, 1.0),
                1 => (
                    vec![rng.range(1e-6, 1e-3), 1.0 - rng.range(1e-6, 1e-3)],
                    0.0,
                    1.0,
                ),
                // A narrow U (a window about a ray's crossing), off its interval's middle.
                _ => {
                    let (r, h) = (rng.range(0.3, 0.7), 10f64.powf(rng.range(-9.0, -1.0)));
                    let reach = |rng: &mut crate::test_rng::Lcg| h * rng.range(1.5, 4.0);
                    let (lo, hi) = (r - reach(&mut rng), r + reach(&mut rng));
                    (vec![r - h, r + h], lo, hi)
                }
            };
            let f = Gentle {
                roots: [roots[0], roots[1]],
                k: rng.range(-0.03, 0.03),
                w: rng.range(0.0, 0.003),
            };
            let counted = Counted::new(&f);
            let mut out = ArrayVec::new();
            assert!(isolate_roots(&counted, lo, hi, &shaped, &mut out));
            assert_both_find(&out, &out, &roots, case);
            one_pair += usize::from(counted.enclosures.get() == 1);
        }
        assert!(
            one_pair >= 540,
            "{one_pair} of 600 U's took one pair of models"
        );
        // A W: the lower side holds three roots.
        let w = Product {
            roots: vec![0.1, 0.2, 0.3, 0.9],
        };
        let mut out = ArrayVec::new();
        assert!(isolate_roots(&w, 0.0, 1.0, &shaped, &mut out));
        assert_both_find(&out, &out, &w.roots, 600);
        // A U with a wiggle on its lower side: a pair of roots 1e-4 apart there.
        let wiggle = Product {
            roots: vec![0.2, 0.3, 0.3001, 0.8],
        };
        let mut out = ArrayVec::new();
        assert!(isolate_roots(&wiggle, 0.0, 1.0, &shaped, &mut out));
        assert_both_find(&out, &out, &wiggle.roots, 601);
    }

    /// A function positive at both ends with a minimum a little above or below zero inside (a
    /// ray that passes a fiber at a graze or clips it: `(u - c)^2 w(u) + delta`, `|delta|`
    /// from 1e-12 to 1e-2, `w` positive and wobbling): with `delta > 0` no root, proved with
    /// fewer pairs than halving alone takes (the cell about the minimum is ruled out by the
    /// value there and the model of `f'`, `slope_bound`: 10,262 pairs for these 1,000
    /// isolations, 12,626 without it); with `delta < 0` both roots, `c -+ sqrt(-delta / w)`
    /// to 1e-9 relative, as the bound must never rule out a dip below zero.
    #[test]
    fn grazing_minima_are_ruled_out_and_dips_kept() {
        struct Graze {
            c: f64,
            delta: f64,
        }
        impl Function1D for Graze {
            fn eval<T: Real>(&self, u: T) -> T {
                let w = T::cst(1.5) + (u.scale(7.0)).sin().scale(0.5);
                (u - T::cst(self.c)).sqr() * w + T::cst(self.delta)
            }
        }
        let mut rng = crate::test_rng::Lcg(101);
        let (mut pairs, mut functions, mut dips) = (0, 0, 0);
        for case in 0..1000 {
            let above = case % 2 == 0;
            let size = 10f64.powf(rng.range(-12.0, -2.0));
            let f = Graze {
                c: rng.range(0.1, 0.9),
                delta: if above { size } else { -size },
            };
            for u_shaped in [false, true] {
                let opts = IsolateOptions {
                    u_shaped,
                    tangent_tolerance: 1e-15,
                    ..Default::default()
                };
                let counted = Counted::new(&f);
                let mut out = ArrayVec::new();
                assert!(isolate_roots(&counted, 0.0, 1.0, &opts, &mut out), "budget");
                if above {
                    assert!(out.is_empty(), "case {case}: no roots: {out:?}");
                    pairs += counted.enclosures.get();
                    functions += 1;
                    continue;
                }
                assert_eq!(out.len(), 2, "case {case}: delta {}: {out:?}", f.delta);
                for (r, side) in out.iter().zip([-1.0, 1.0]) {
                    // (r - c)^2 w(r) = -delta, so r - c = -+ sqrt(-delta / w(r)).
                    let w = 1.5 + 0.5 * (7.0 * r).sin();
                    let want = f.c + side * (-f.delta / w).sqrt();
                    assert!(
                        (r - want).abs() <= 1e-9 * (r - f.c).abs(),
                        "case {case}: root {r} against {want}"
                    );
                }
                dips += 1;
            }
        }
        assert!(
            functions == 1000 && dips == 1000 && pairs <= 11 * functions,
            "{pairs} pairs for {functions} functions without roots, {dips} with"
        );
    }

    /// Where `f` has one sign at both ends of a cell the isolator first encloses `f` alone (a
    /// third of the work of `f` and `f'` together): on products whose roots all lie outside
    /// `[0, 1]` (some within 1e-3 of it) every cell is enclosed so first, about half of them
    /// are ruled out that way, without the pair (near the roots the value models are too
    /// wide), and no root is reported. Where the ends differ in sign the pair comes first.
    #[test]
    fn one_sign_cells_are_ruled_out_by_the_value_alone() {
        let mut rng = crate::test_rng::Lcg(5);
        let (mut values, mut pairs) = (0, 0);
        for case in 0..500 {
            let n = 2 + case % 3;
            let roots: Vec<f64> = (0..n)
                .map(|k| {
                    let gap = if case % 2 == 0 { 1e-3 } else { 0.5 } * rng.next();
                    if k % 2 == 0 {
                        -gap - 1e-9
                    } else {
                        1.0 + gap + 1e-9
                    }
                })
                .collect();
            let f = Product { roots };
            let counted = Counted::new(&f);
            let mut out = ArrayVec::new();
            let opts = IsolateOptions::default();
            assert!(isolate_roots(&counted, 0.0, 1.0, &opts, &mut out), "budget");
            assert!(
                out.is_empty(),
                "case {case}: no root in [0, 1], got {out:?}"
            );
            // Every cell has one sign at its ends here: no pair without a value model first.
            assert!(
                counted.enclosures.get() <= counted.values.get(),
                "case {case}"
            );
            values += counted.values.get();
            pairs += counted.enclosures.get();
        }
        assert!(
            values >= 500 && 10 * pairs <= 6 * values,
            "{values} value enclosures, {pairs} pairs"
        );
        // A sign change at the ends: the pair at once (which proves `u - 0.3` monotone).
        struct Line;
        impl Function1D for Line {
            fn eval<T: Real>(&self, u: T) -> T {
                u - T::cst(0.3)
            }
        }
        let counted = Counted::new(&Line);
        let mut out = ArrayVec::new();
        isolate_roots(&counted, 0.0, 1.0, &IsolateOptions::default(), &mut out);
        assert_eq!((counted.values.get(), counted.enclosures.get()), (0, 1));
        assert!(out.len() == 1 && (out[0] - 0.3).abs() < 1e-15, "{out:?}");
    }

    /// With [`IsolateOptions::u_shaped`] the isolator finds the same roots as without, to
    /// full precision: functions positive at both ends with two or four roots (a U, a W, roots
    /// on one side of the middle, at it, 1e-6 apart, within 1e-9 of the ends or of the middle,
    /// far from where the parabola through the ends and the middle puts them), a double root,
    /// none. Where the middle is negative the interval is cut there at least; where two roots
    /// at least 0.02 apart lie off the middle, at 90% of the time (the vertex of the parabola
    /// through the ends and the middle; the wobble bends it); the cells tile the interval at
    /// negative values; and on the plain U (one root on each side of the middle) the
    /// isolation takes fewer enclosures of `f` with `f'` than without the cells (here 10%
    /// fewer: the wobble keeps some sides from being monotone at once).
    #[test]
    fn u_shaped_cells_find_the_same_roots() {
        let mut rng = crate::test_rng::Lcg(47);
        let mut rnd = || rng.next();
        let (mut split, mut off_centre, mut enclosures) = (0, [0, 0], [0, 0]);
        for case in 0..2000 {
            let mut roots: Vec<f64> = match case % 8 {
                0 => vec![0.5 - 0.5 * rnd(), 0.5 + 0.5 * rnd()],
                1 => vec![1e-9 + 1e-3 * rnd(), 1.0 - 1e-9 - 1e-3 * rnd()],
                2 => vec![0.5 - 1e-9 * (1.0 + rnd()), 0.5 + 1e-9 * (1.0 + rnd())],
                3 => (0..4).map(|_| rnd()).collect(),
                4 => vec![0.05 + 0.4 * rnd(), 0.45 + 0.04 * rnd()],
                5 => {
                    let r = 0.1 + 0.8 * rnd();
                    vec![r, r + 1e-6]
                }
                6 => vec![0.5, 0.3 * rnd() + 0.6],
                _ => vec![rnd(), rnd(), 0.5 * rnd(), 0.5 + 0.5 * rnd()],
            };
            roots.sort_by(f64::total_cmp);
            let f = Product { roots };
            let plain = IsolateOptions::default();
            let shaped = IsolateOptions {
                u_shaped: true,
                ..plain
            };
            let (mut a, mut b) = (ArrayVec::new(), ArrayVec::new());
            let count = |opts: &IsolateOptions, out: &mut ArrayVec<f64, MAX_ROOTS>| {
                let counted = Counted::new(&f);
                assert!(isolate_roots(&counted, 0.0, 1.0, opts, out), "budget");
                counted.enclosures.get()
            };
            let (without, with) = (count(&plain, &mut a), count(&shaped, &mut b));
            if case % 8 == 0 {
                enclosures[0] += without;
                enclosures[1] += with;
            }
            assert_both_find(&a, &b, &f.roots, case);
            let point = |u: f64| f.eval(u);
            let FirstCells { cells, .. } = u_shaped_cells(
                &point,
                (0.0, 1.0),
                (point(0.0), point(1.0)),
                FirstRoot::Both,
            );
            if point(0.5) < 0.0 {
                split += 1;
                assert!(cells.len() >= 2, "case {case}: cut at the middle at least");
            } else if f.roots.len() == 2 && f.roots[1] - f.roots[0] > 0.02 {
                // Negative between two roots off the middle: cut where the parabola through
                // the ends and the middle has its vertex, mostly.
                off_centre[0] += 1;
                off_centre[1] += usize::from(cells.len() >= 2);
            }
            // The cells cover [0, 1] in order, and their cut points are no roots.
            assert_eq!((cells[0].0, cells[cells.len() - 1].1), (0.0, 1.0));
            for w in cells.windows(2) {
                assert!(
                    w[0].1 == w[1].0 && w[0].3 == w[1].2 && w[0].3 < 0.0,
                    "{cells:?}"
                );
            }
        }
        assert!(split > 900, "most cases are U-shaped: {split}");
        assert!(
            off_centre[0] > 300 && 10 * off_centre[1] >= 9 * off_centre[0],
            "U-shaped off the middle: {off_centre:?} (all, cut)"
        );
        assert!(
            20 * enclosures[1] <= 19 * enclosures[0],
            "plain U: {} enclosures with the cells against {} without",
            enclosures[1],
            enclosures[0]
        );
        let tangent = |u: f64| Tangent.eval(u);
        for f in [&tangent as &dyn Fn(f64) -> f64, &|u: f64| 1.0 + u * u] {
            let FirstCells { cells, .. } =
                u_shaped_cells(&f, (0.0, 1.0), (f(0.0), f(1.0)), FirstRoot::Both);
            assert_eq!(cells.len(), 1, "no negative middle, no cut");
        }
        let mut out = ArrayVec::new();
        let shaped = IsolateOptions {
            u_shaped: true,
            ..IsolateOptions::default()
        };
        isolate_roots(&Tangent, 0.0, 1.0, &shaped, &mut out);
        assert!(
            out.len() == 1 && (out[0] - 0.3).abs() < 1e-9,
            "double root {out:?}"
        );
    }

    /// A whole interval whose samples dip below both ends' values (a ray passing close by a
    /// fiber: `g` positive throughout, least inside) is flagged [`Hints::dips`]; an interval
    /// cut about a negative middle, or whose samples do not dip, is not. The flag only skips
    /// the value model of that interval's first cell, which the pair's value part repeats to
    /// the bit: with and without it the isolation finds the same roots, bit for bit, on near
    /// misses (minima from 1e-9 to 1e-1 above zero, anywhere in the interval, with a wobble),
    /// grazes (a double root), and functions with two or four roots, and one value model fewer
    /// for every flagged interval.
    #[test]
    fn dipping_intervals_go_straight_to_the_pair() {
        struct Dip {
            at: f64,
            least: f64,
            roots: Vec<f64>,
        }
        impl Function1D for Dip {
            fn eval<T: Real>(&self, u: T) -> T {
                let wobble = T::cst(1.0) + (u.scale(7.0)).sin().scale(0.1);
                let bowl = (u - T::cst(self.at)).sqr() + T::cst(self.least);
                self.roots
                    .iter()
                    .fold(bowl * wobble, |acc, &r| acc * (u - T::cst(r)))
            }
        }
        let mut rng = crate::test_rng::Lcg(59);
        let mut rnd = || rng.next();
        let opts = IsolateOptions {
            u_shaped: true,
            ..IsolateOptions::default()
        };
        let (mut flagged, mut saved) = (0, 0);
        for case in 0..1500 {
            let least = match case % 5 {
                4 => 0.0,
                _ => 10f64.powf(-9.0 + 8.0 * rnd()),
            };
            let f = Dip {
                at: 0.3 + 0.4 * rnd(),
                least,
                roots: match case % 15 {
                    3 => vec![-0.5, 1.5],
                    8 => vec![-0.7, -0.2, 1.2, 1.9],
                    13 => vec![0.2 * rnd() - 0.5, 1.3],
                    _ => vec![],
                },
            };
            let point = |u: f64| f.eval(u);
            let first = first_cells(&f, 0.0, 1.0, &opts, FirstRoot::Both);
            // A bowl alone: the middle sample lies below both ends (the vertex is within 0.2
            // of it, the wobble within 10%), positive but at a graze: one whole cell, flagged.
            let bowl = f.roots.is_empty() && least > 0.0;
            let whole = first.cells.len() == 1 && point(0.0) > 0.0 && point(1.0) > 0.0;
            assert!(!bowl || first.hints.dips, "case {case}: {:?}", first.cells);
            assert!(!first.hints.dips || whole, "case {case}: {:?}", first.cells);
            let run = |hints: Hints| {
                let counted = Counted::new(&f);
                let mut out = ArrayVec::new();
                let found = isolate_in_cells(&counted, &first.cells, hints, &opts, &mut out);
                assert!(found.complete && !found.overflow, "case {case}");
                (out, counted.values.get())
            };
            let (with, values_with) = run(first.hints);
            let (without, values_without) = run(first.hints.for_part());
            assert_eq!(with, without, "case {case}: the same roots, bit for bit");
            if first.hints.dips {
                flagged += 1;
                saved += values_without - values_with;
                assert_eq!(values_without, values_with + 1, "case {case}");
            } else {
                assert_eq!(values_without, values_with, "case {case}");
            }
            // A bowl has no root, a grazed one its double root (reported once).
            if f.roots.is_empty() {
                let expected = if least > 0.0 { 0 } else { 1 };
                assert_eq!(with.len(), expected, "case {case}: {with:?}");
            }
        }
        assert!(flagged > 600, "the bowls at least are flagged: {flagged}");
        assert_eq!(saved, flagged);
        // A monotone function samples no dip; a negative middle is cut, not flagged.
        let rising = |u: f64| 1.0 + u;
        let FirstCells { cells, hints, .. } =
            u_shaped_cells(&rising, (0.0, 1.0), (1.0, 2.0), FirstRoot::Both);
        assert!(cells.len() == 1 && !hints.dips);
        let u = |u: f64| (u - 0.3) * (u - 0.7);
        let FirstCells { cells, hints, .. } =
            u_shaped_cells(&u, (0.0, 1.0), (u(0.0), u(1.0)), FirstRoot::Both);
        assert!(cells.len() == 3 && !hints.dips, "{cells:?}");
    }

    /// `local_zero` is the zero in the cell of the parabola through the three points: exact
    /// (to 1e-15 of the cell) where `f` is that parabola, for cells left and right of the
    /// third point, narrow and wide, roots near either end; `None` where the parabola's zero
    /// lies outside the cell. On a U-shaped cubic (a parabola tilted), the estimates of
    /// `u_shaped_cells` (from each side's own ends and the middle) are closer to the roots
    /// than the zeros of the parabola through the whole interval's ends and middle (the
    /// median error four times smaller at least).
    #[test]
    fn local_zeros_are_the_sides_parabolas_zeros() {
        let mut rng = crate::test_rng::Lcg(61);
        let mut rnd = || rng.next();
        for case in 0..2000 {
            let (r1, r2) = (0.4 * rnd(), 0.6 + 0.4 * rnd());
            let k = 10f64.powf(-3.0 + 6.0 * rnd());
            let f = |u: f64| k * (u - r1) * (u - r2);
            let width = 10f64.powf(-6.0 * rnd());
            // A cell about r1 (f falls through zero), the third point to its right.
            let a = r1 - width * rnd();
            let b = a + width;
            if !(b < 0.5) {
                continue;
            }
            let z = local_zero((a, f(a)), (b, f(b)), (0.5, f(0.5))).expect("a zero");
            assert!(
                (z - r1).abs() <= 1e-15 + 1e-13 * width,
                "case {case}: {z} {r1}"
            );
            // A cell about r2, the third point to its left.
            let a = r2 - width * rnd();
            let b = a + width;
            let z = local_zero((a, f(a)), (b, f(b)), (0.5, f(0.5))).expect("a zero");
            assert!(
                (z - r2).abs() <= 1e-15 + 1e-13 * width,
                "case {case}: {z} {r2}"
            );
        }
        // The parabola through (0, 1), (0.1, 0.5), (0.5, 0.2) stays positive: no zero.
        assert_eq!(local_zero((0.0, 1.0), (0.1, 0.5), (0.5, 0.2)), None);
        // A U that is not a parabola: the sides' estimates beat the whole interval's.
        let (mut local, mut global) = (Vec::new(), Vec::new());
        for case in 0..200 {
            let (r1, r2) = (0.1 + 0.3 * rnd(), 0.6 + 0.3 * rnd());
            let tilt = 0.6 * rnd() - 0.3;
            let f = |u: f64| (u - r1) * (u - r2) * (1.0 + tilt * (u - 0.5));
            let FirstCells { cells, hints, .. } =
                u_shaped_cells(&f, (0.0, 1.0), (f(0.0), f(1.0)), FirstRoot::Both);
            assert_eq!(cells.len(), 3, "case {case}");
            let (m, fm) = (0.5, f(0.5));
            // The zeros of the whole interval's parabola (through 0, m and 1).
            let (c2, c1) = ((f(0.0) - 2.0 * fm + f(1.0)) / 0.5, f(1.0) - f(0.0));
            let disc = (c1 * c1 - 4.0 * c2 * fm).sqrt();
            let whole = [m + (-c1 - disc) / (2.0 * c2), m + (-c1 + disc) / (2.0 * c2)];
            for (i, r) in [r1, r2].into_iter().enumerate() {
                local.push((hints.guesses[i] - r).abs());
                global.push((whole[i] - r).abs());
            }
        }
        local.sort_by(f64::total_cmp);
        global.sort_by(f64::total_cmp);
        let (local, global) = (local[local.len() / 2], global[global.len() / 2]);
        assert!(
            4.0 * local < global,
            "medians: sides {local:e}, whole {global:e}"
        );
    }

    /// The Taylor-model isolator and the interval reference find the same roots, to full
    /// precision: up to six simple roots, some pairs only 1e-6 apart.
    #[test]
    fn isolate_matches_the_reference() {
        let mut rng = crate::test_rng::Lcg(31);
        let mut rnd = || rng.next();
        for case in 0..300 {
            let n = 1 + case % 6;
            let mut roots: Vec<f64> = (0..n).map(|_| 0.02 + 0.96 * rnd()).collect();
            if case % 3 == 0 {
                let r = roots[0];
                roots.push(r + 1e-6);
            }
            roots.sort_by(f64::total_cmp);
            let f = Product { roots };
            let (mut fast, mut reference) = (ArrayVec::new(), ArrayVec::new());
            let opts = IsolateOptions::default();
            assert!(isolate_roots(&f, 0.0, 1.0, &opts, &mut fast), "budget");
            assert!(isolate_roots_reference(&f, 0.0, 1.0, &opts, &mut reference));
            assert_both_find(&fast, &reference, &f.roots, case);
        }
    }
}
