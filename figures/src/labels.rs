//! Text labels placed off the curves: each label takes the first of a few
//! positions around its point whose box crosses no curve, no label placed
//! before it and stays inside the plot; where none is free, the one
//! crossing the fewest.

/// A box in pixels: `(left, top)` to `(right, bottom)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Rect {
    pub(crate) x0: i32,
    pub(crate) y0: i32,
    pub(crate) x1: i32,
    pub(crate) y1: i32,
}

impl Rect {
    pub(crate) fn overlaps(&self, o: &Rect) -> bool {
        self.x0 < o.x1 && o.x0 < self.x1 && self.y0 < o.y1 && o.y0 < self.y1
    }
    fn contains(&self, o: &Rect) -> bool {
        self.x0 <= o.x0 && o.x1 <= self.x1 && self.y0 <= o.y0 && o.y1 <= self.y1
    }
    /// Whether the segment `a`–`b` passes through the box (Liang–Barsky
    /// clipping).
    pub(crate) fn hit_by(&self, a: (i32, i32), b: (i32, i32)) -> bool {
        let (ax, ay) = (f64::from(a.0), f64::from(a.1));
        let (dx, dy) = (f64::from(b.0) - ax, f64::from(b.1) - ay);
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        for (p, q) in [
            (-dx, ax - f64::from(self.x0)),
            (dx, f64::from(self.x1) - ax),
            (-dy, ay - f64::from(self.y0)),
            (dy, f64::from(self.y1) - ay),
        ] {
            if p == 0.0 {
                if q < 0.0 {
                    return false;
                }
            } else {
                let r = q / p;
                if p < 0.0 {
                    t0 = t0.max(r);
                } else {
                    t1 = t1.min(r);
                }
            }
        }
        t0 <= t1
    }
    /// Whether any segment of the polyline passes through the box.
    pub(crate) fn hit_by_line(&self, line: &[(i32, i32)]) -> bool {
        match line {
            [p] => self.hit_by(*p, *p),
            _ => line.windows(2).any(|w| self.hit_by(w[0], w[1])),
        }
    }
}

/// The box of a label `size` (w, h) for its point `at`: tried right,
/// left, above, below, then diagonally further out.
fn candidates(at: (i32, i32), size: (u32, u32)) -> Vec<Rect> {
    let (w, h) = (size.0 as i32, size.1 as i32);
    let g = 8;
    let offsets = [
        (g, -h / 2),
        (-g - w, -h / 2),
        (-w / 2, -g - h),
        (-w / 2, g),
        (g, g),
        (g, -g - h),
        (-g - w, g),
        (-g - w, -g - h),
        (2 * g, 3 * g),
        (2 * g, -3 * g - h),
        (-2 * g - w, 3 * g),
        (-2 * g - w, -3 * g - h),
    ];
    offsets
        .iter()
        .map(|&(dx, dy)| Rect {
            x0: at.0 + dx,
            y0: at.1 + dy,
            x1: at.0 + dx + w,
            y1: at.1 + dy + h,
        })
        .collect()
}

/// Place labels of `sizes` at the points `at`, in turn, off `lines` (pixel
/// polylines) and each other, inside `inside`: their boxes.
pub(crate) fn place(
    at: &[(i32, i32)],
    sizes: &[(u32, u32)],
    lines: &[Vec<(i32, i32)>],
    inside: Rect,
) -> Vec<Rect> {
    let mut placed: Vec<Rect> = Vec::new();
    for (&p, &s) in at.iter().zip(sizes) {
        let cost = |r: &Rect| {
            let crossed = lines.iter().filter(|l| r.hit_by_line(l)).count();
            let covered = placed.iter().filter(|o| o.overlaps(r)).count();
            let out = usize::from(!inside.contains(r));
            crossed + covered + 2 * out
        };
        let options = candidates(p, s);
        let best = options
            .iter()
            .copied()
            .find(|r| cost(r) == 0)
            .or_else(|| options.iter().copied().min_by_key(|r| cost(r)));
        if let Some(r) = best {
            placed.push(r);
        }
    }
    placed
}

#[cfg(test)]
mod tests {
    use super::*;

    const PLOT: Rect = Rect {
        x0: 0,
        y0: 0,
        x1: 400,
        y1: 300,
    };

    #[test]
    fn a_segment_hits_a_box_only_where_it_passes_through() {
        let r = Rect {
            x0: 10,
            y0: 10,
            x1: 20,
            y1: 20,
        };
        assert!(r.hit_by((0, 15), (30, 15)));
        assert!(r.hit_by((0, 0), (30, 30)));
        assert!(r.hit_by((12, 12), (13, 13)));
        assert!(!r.hit_by((0, 25), (30, 25)));
        assert!(!r.hit_by((0, 0), (30, 5)));
        assert!(!r.hit_by((25, 0), (25, 30)));
    }

    #[test]
    fn a_label_moves_off_a_curve_running_through_its_first_place() {
        // A horizontal curve through the point: right of it is taken.
        let curve = vec![(0, 100), (400, 100)];
        let r = place(
            &[(200, 100)],
            &[(80, 18)],
            std::slice::from_ref(&curve),
            PLOT,
        );
        assert_eq!(r.len(), 1);
        assert!(!r[0].hit_by_line(&curve), "{r:?}");
        assert!(PLOT.contains(&r[0]));
    }

    #[test]
    fn labels_avoid_each_other_and_stay_inside() {
        let at = [(390, 150), (390, 160), (390, 170)];
        let r = place(&at, &[(80, 18); 3], &[], PLOT);
        for (i, a) in r.iter().enumerate() {
            assert!(PLOT.contains(a), "{a:?}");
            for b in &r[i + 1..] {
                assert!(!a.overlaps(b), "{a:?} {b:?}");
            }
        }
    }
}
