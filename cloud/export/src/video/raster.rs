//! A small RGB rasterizer: filled polygons (even-odd rule, sampled at pixel centres), thick line
//! segments and polylines as filled quads, axis-aligned rectangles. Enough for a bird's-eye view of
//! vehicles and their paths; no anti-aliasing.

/// A colour.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rgb(pub u8, pub u8, pub u8);

impl Rgb {
    /// This colour mixed with `other`, `amount` of `other` in [0, 1].
    pub fn mix(self, other: Self, amount: f64) -> Self {
        let a = amount.clamp(0.0, 1.0);
        let m = |x: u8, y: u8| (f64::from(x) * (1.0 - a) + f64::from(y) * a).round().clamp(0.0, 255.0) as u8;
        Self(m(self.0, other.0), m(self.1, other.1), m(self.2, other.2))
    }
}

/// An RGB24 image, rows top to bottom, the layout `ffmpeg -f rawvideo -pix_fmt rgb24` reads.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Canvas {
    width: u32,
    height: u32,
    data: Vec<u8>,
}

impl Canvas {
    /// A canvas filled with `background`.
    pub fn new(width: u32, height: u32, background: Rgb) -> Self {
        let pixels = width as usize * height as usize;
        let data = [background.0, background.1, background.2].repeat(pixels);
        Self { width, height, data }
    }

    /// Width, px.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height, px.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The pixels, 3 bytes each.
    pub fn as_bytes(&self) -> &[u8] {
        &self.data
    }

    /// Copies `other`'s pixels into this canvas when both have the same size.
    pub fn copy_from(&mut self, other: &Self) {
        if self.data.len() == other.data.len() {
            self.data.copy_from_slice(&other.data);
        }
    }

    /// The colour at (x, y), if inside.
    pub fn pixel(&self, x: u32, y: u32) -> Option<Rgb> {
        let i = self.index(i64::from(x), i64::from(y))?;
        let p = self.data.get(i..i + 3)?;
        Some(Rgb(*p.first()?, *p.get(1)?, *p.get(2)?))
    }

    fn index(&self, x: i64, y: i64) -> Option<usize> {
        if x < 0 || y < 0 || x >= i64::from(self.width) || y >= i64::from(self.height) {
            return None;
        }
        usize::try_from((y * i64::from(self.width) + x) * 3).ok()
    }

    /// Fills pixels `x_from..x_to` of row `y` (clipped).
    fn span(&mut self, y: i64, x_from: i64, x_to: i64, c: Rgb) {
        let x_from = x_from.max(0);
        let x_to = x_to.min(i64::from(self.width));
        if x_from >= x_to {
            return;
        }
        let (Some(a), Some(b)) = (self.index(x_from, y), self.index(x_to - 1, y)) else {
            return;
        };
        if let Some(row) = self.data.get_mut(a..b + 3) {
            for px in row.chunks_exact_mut(3) {
                px.copy_from_slice(&[c.0, c.1, c.2]);
            }
        }
    }

    /// Fills the axis-aligned rectangle of pixels `[x0, x1) × [y0, y1)` (clipped).
    pub fn fill_rect(&mut self, x0: i64, y0: i64, x1: i64, y1: i64, c: Rgb) {
        for y in y0.max(0)..y1.min(i64::from(self.height)) {
            self.span(y, x0, x1, c);
        }
    }

    /// Fills a polygon given by its vertices in pixel coordinates (even-odd rule; a pixel is in
    /// when its centre is). Points that are not finite leave the canvas unchanged.
    pub fn fill_polygon(&mut self, pts: &[(f64, f64)], c: Rgb) {
        if pts.len() < 3 || pts.iter().any(|p| !(p.0.is_finite() && p.1.is_finite())) {
            return;
        }
        let (lo, hi) = pts.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| (lo.min(p.1), hi.max(p.1)));
        let y_first = ((lo - 0.5).ceil() as i64).max(0);
        let y_last = ((hi - 0.5).floor() as i64).min(i64::from(self.height) - 1);
        let mut crossings: Vec<f64> = Vec::with_capacity(8);
        for y in y_first..=y_last {
            let yc = y as f64 + 0.5;
            crossings.clear();
            for (i, p) in pts.iter().enumerate() {
                let q = pts.get(i + 1).or(pts.first()).unwrap_or(p);
                if (p.1 <= yc) != (q.1 <= yc) {
                    crossings.push(p.0 + (yc - p.1) * (q.0 - p.0) / (q.1 - p.1));
                }
            }
            crossings.sort_by(f64::total_cmp);
            for pair in crossings.chunks_exact(2) {
                if let [a, b] = pair {
                    // Pixels whose centre x + 0.5 lies in [a, b).
                    let from = (a - 0.5).ceil().clamp(-1.0, f64::from(self.width) + 1.0) as i64;
                    let to = (b - 0.5).ceil().clamp(-1.0, f64::from(self.width) + 1.0) as i64;
                    self.span(y, from, to, c);
                }
            }
        }
    }

    /// Draws a segment `width` px wide as a filled quad.
    pub fn line(&mut self, a: (f64, f64), b: (f64, f64), width: f64, c: Rgb) {
        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
        let len = dx.hypot(dy);
        let half = width.max(1.0) / 2.0;
        if !len.is_finite() || len <= 1e-9 {
            self.fill_polygon(
                &[
                    (a.0 - half, a.1 - half),
                    (a.0 + half, a.1 - half),
                    (a.0 + half, a.1 + half),
                    (a.0 - half, a.1 + half),
                ],
                c,
            );
            return;
        }
        let (nx, ny) = (-dy / len * half, dx / len * half);
        // Extended by half the width at both ends, so that the segments of a polyline join.
        let (ex, ey) = (dx / len * half, dy / len * half);
        self.fill_polygon(
            &[
                (a.0 + nx - ex, a.1 + ny - ey),
                (b.0 + nx + ex, b.1 + ny + ey),
                (b.0 - nx + ex, b.1 - ny + ey),
                (a.0 - nx - ex, a.1 - ny - ey),
            ],
            c,
        );
    }

    /// Draws a polyline `width` px wide.
    pub fn polyline(&mut self, pts: &[(f64, f64)], width: f64, c: Rgb) {
        for pair in pts.windows(2) {
            if let [a, b] = pair {
                self.line(*a, *b, width, c);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]

    use super::*;

    const BG: Rgb = Rgb(0, 0, 0);
    const FG: Rgb = Rgb(255, 255, 255);

    fn count(c: &Canvas, colour: Rgb) -> usize {
        c.as_bytes().chunks_exact(3).filter(|p| *p == [colour.0, colour.1, colour.2]).count()
    }

    #[test]
    fn an_axis_aligned_square_covers_exactly_its_pixels() {
        let mut c = Canvas::new(10, 8, BG);
        c.fill_polygon(&[(2.0, 1.0), (6.0, 1.0), (6.0, 4.0), (2.0, 4.0)], FG);
        assert_eq!(count(&c, FG), 4 * 3);
        assert_eq!(c.pixel(2, 1), Some(FG));
        assert_eq!(c.pixel(5, 3), Some(FG));
        assert_eq!(c.pixel(6, 3), Some(BG));
        assert_eq!(c.pixel(1, 1), Some(BG));
        assert_eq!(c.as_bytes().len(), 10 * 8 * 3);
    }

    #[test]
    fn a_rotated_square_keeps_its_area_and_clipping_is_safe() {
        let mut c = Canvas::new(100, 100, BG);
        // A 40 px square turned by 45°, centred at (50, 50).
        let r = 20.0 * std::f64::consts::SQRT_2;
        c.fill_polygon(&[(50.0 - r, 50.0), (50.0, 50.0 - r), (50.0 + r, 50.0), (50.0, 50.0 + r)], FG);
        let area = count(&c, FG) as f64;
        assert!((area - 1600.0).abs() < 60.0, "{area}");
        // Far outside, partly outside, NaN: no panic, only what is inside is drawn.
        c.fill_polygon(&[(-1e9, -1e9), (1e9, -1e9), (1e9, 1e9)], Rgb(1, 2, 3));
        c.fill_polygon(&[(f64::NAN, 0.0), (3.0, 3.0), (0.0, 3.0)], Rgb(9, 9, 9));
        assert_eq!(count(&c, Rgb(9, 9, 9)), 0);
        c.fill_rect(-5, -5, 3, 2, FG);
        assert_eq!(c.pixel(0, 0), Some(FG));
        assert_eq!(c.pixel(100, 0), None);
    }

    #[test]
    fn a_thick_line_has_its_width() {
        let mut c = Canvas::new(50, 20, BG);
        c.line((5.0, 10.0), (45.0, 10.0), 3.0, FG);
        let column: Vec<bool> = (0..20).map(|y| c.pixel(20, y) == Some(FG)).collect();
        assert_eq!(column.iter().filter(|b| **b).count(), 3);
        c.polyline(&[(1.0, 1.0), (1.0, 1.0)], 2.0, FG);
        assert_eq!(c.pixel(1, 1), Some(FG));
        assert_eq!(Rgb(0, 0, 0).mix(Rgb(200, 100, 50), 0.5), Rgb(100, 50, 25));
    }
}
