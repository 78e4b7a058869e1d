//! A rasterised distance-to-track field and the marching-squares tracing of
//! a level set of it into polylines.

use crate::sim::geometry::point_segment_distance;
use nalgebra::{Point2, Vector2};

/// Distance to a polyline sampled on the vertices of a square grid; values
/// are capped at `reach` (farther points hold `reach`).
pub struct DistanceField {
    origin: Point2<f64>,
    cell_m: f64,
    cols: usize,
    rows: usize,
    values: Vec<f64>,
}

impl DistanceField {
    pub fn new(track: &[Point2<f64>], cell_m: f64, reach: f64) -> Self {
        let (mut lo, mut hi) = (Point2::new(0.0, 0.0), Point2::new(1.0, 1.0));
        if let Some(first) = track.first() {
            (lo, hi) = (*first, *first);
            for p in track {
                lo = lo.inf(p);
                hi = hi.sup(p);
            }
        }
        let margin = Vector2::repeat(reach + 2.0 * cell_m);
        let origin = lo - margin;
        let cols = (((hi.x - lo.x) + 2.0 * margin.x) / cell_m).ceil() as usize + 1;
        let rows = (((hi.y - lo.y) + 2.0 * margin.y) / cell_m).ceil() as usize + 1;
        let mut field = Self {
            origin,
            cell_m,
            cols,
            rows,
            values: vec![reach; cols * rows],
        };
        let segments: Vec<(Point2<f64>, Point2<f64>)> = match track.len() {
            0 => Vec::new(),
            1 => vec![(track[0], track[0])],
            _ => track.windows(2).map(|w| (w[0], w[1])).collect(),
        };
        for (a, b) in segments {
            field.stamp_segment(a, b, reach);
        }
        field
    }

    fn stamp_segment(&mut self, a: Point2<f64>, b: Point2<f64>, reach: f64) {
        let lo = a.inf(&b) - Vector2::repeat(reach);
        let hi = a.sup(&b) + Vector2::repeat(reach);
        let i0 = ((lo.x - self.origin.x) / self.cell_m).floor().max(0.0) as usize;
        let j0 = ((lo.y - self.origin.y) / self.cell_m).floor().max(0.0) as usize;
        let i1 = (((hi.x - self.origin.x) / self.cell_m).ceil() as usize).min(self.cols - 1);
        let j1 = (((hi.y - self.origin.y) / self.cell_m).ceil() as usize).min(self.rows - 1);
        for j in j0..=j1 {
            for i in i0..=i1 {
                let d = point_segment_distance(self.vertex(i, j), a, b);
                let v = &mut self.values[j * self.cols + i];
                if d < *v {
                    *v = d;
                }
            }
        }
    }

    fn vertex(&self, i: usize, j: usize) -> Point2<f64> {
        self.origin + Vector2::new(i as f64, j as f64) * self.cell_m
    }

    pub fn bounds(&self) -> (Point2<f64>, Point2<f64>) {
        (self.vertex(0, 0), self.vertex(self.cols - 1, self.rows - 1))
    }

    /// Bilinear interpolation of the field at `p` (clamped to the grid).
    pub fn distance(&self, p: Point2<f64>) -> f64 {
        let u = ((p.x - self.origin.x) / self.cell_m).clamp(0.0, (self.cols - 1) as f64 - 1e-9);
        let v = ((p.y - self.origin.y) / self.cell_m).clamp(0.0, (self.rows - 1) as f64 - 1e-9);
        let (i, j) = (u.floor() as usize, v.floor() as usize);
        let (fu, fv) = (u - i as f64, v - j as f64);
        let at = |i: usize, j: usize| self.values[j * self.cols + i];
        let bottom = at(i, j) * (1.0 - fu) + at(i + 1, j) * fu;
        let top = at(i, j + 1) * (1.0 - fu) + at(i + 1, j + 1) * fu;
        bottom * (1.0 - fv) + top * fv
    }

    /// Unit vector of steepest descent of the distance (towards the track)
    /// at `p`, or `None` on a flat spot.
    pub fn descent_direction(&self, p: Point2<f64>) -> Option<Vector2<f64>> {
        let h = self.cell_m;
        let gx = self.distance(p + Vector2::new(h, 0.0)) - self.distance(p - Vector2::new(h, 0.0));
        let gy = self.distance(p + Vector2::new(0.0, h)) - self.distance(p - Vector2::new(0.0, h));
        let g = Vector2::new(-gx, -gy);
        (g.norm() > 1e-6).then(|| g.normalize())
    }
}

/// Corner pairs of the four edges of a square: bottom, right, top, left
/// (corners 0..4 counter-clockwise from the lower left).
const EDGE_CORNERS: [(usize, usize); 4] = [(0, 1), (1, 2), (3, 2), (0, 3)];

/// The zero level of `level(vertex, distance)` traced by marching squares
/// into polylines (closed ones repeat their first point at the end).
/// Negative values are inside (water).
pub fn trace_contours<L>(field: &DistanceField, level: L) -> Vec<Vec<Point2<f64>>>
where
    L: Fn(Point2<f64>, f64) -> f64,
{
    let (cols, rows) = (field.cols, field.rows);
    let g: Vec<f64> = (0..rows * cols)
        .map(|k| {
            let (i, j) = (k % cols, k / cols);
            level(field.vertex(i, j), field.values[k])
        })
        .collect();
    let edge_id = |i: usize, j: usize, e: usize| -> usize {
        match e {
            0 => 2 * (j * cols + i),
            1 => 2 * (j * cols + i + 1) + 1,
            2 => 2 * ((j + 1) * cols + i),
            _ => 2 * (j * cols + i) + 1,
        }
    };
    let mut segments: Vec<[usize; 2]> = Vec::new();
    let mut crossing = vec![Point2::origin(); 2 * cols * rows];
    for j in 0..rows - 1 {
        for i in 0..cols - 1 {
            let corners = [(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)];
            let v: Vec<f64> = corners.iter().map(|&(a, b)| g[b * cols + a]).collect();
            let mask = (0..4).fold(0, |m, k| m | (usize::from(v[k] < 0.0) << k));
            let centre_inside = v.iter().sum::<f64>() < 0.0;
            for &(ea, eb) in edge_pairs(mask, centre_inside) {
                for e in [ea, eb] {
                    let (ca, cb) = EDGE_CORNERS[e];
                    let f = v[ca] / (v[ca] - v[cb]);
                    let (pa, pb) = (
                        field.vertex(corners[ca].0, corners[ca].1),
                        field.vertex(corners[cb].0, corners[cb].1),
                    );
                    crossing[edge_id(i, j, e)] = pa + (pb - pa) * f;
                }
                segments.push([edge_id(i, j, ea), edge_id(i, j, eb)]);
            }
        }
    }
    chain(&segments, &crossing)
}

/// Edge pairs crossed by the contour in a square with inside-corner `mask`;
/// saddles are resolved by the sign at the centre.
fn edge_pairs(mask: usize, centre_inside: bool) -> &'static [(usize, usize)] {
    match mask {
        1 | 14 => &[(3, 0)],
        2 | 13 => &[(0, 1)],
        3 | 12 => &[(3, 1)],
        4 | 11 => &[(1, 2)],
        6 | 9 => &[(0, 2)],
        7 | 8 => &[(3, 2)],
        5 if centre_inside => &[(0, 1), (2, 3)],
        5 => &[(3, 0), (1, 2)],
        10 if centre_inside => &[(3, 0), (1, 2)],
        10 => &[(0, 1), (2, 3)],
        _ => &[],
    }
}

/// Joins segments that share an edge crossing into polylines.
fn chain(segments: &[[usize; 2]], crossing: &[Point2<f64>]) -> Vec<Vec<Point2<f64>>> {
    const NONE: u32 = u32::MAX;
    let mut by_edge = vec![[NONE; 2]; crossing.len()];
    for (s, pair) in segments.iter().enumerate() {
        for &e in pair {
            let slot = &mut by_edge[e];
            if slot[0] == NONE {
                slot[0] = s as u32;
            } else {
                slot[1] = s as u32;
            }
        }
    }
    let mut used = vec![false; segments.len()];
    let mut chains = Vec::new();
    for start in 0..segments.len() {
        if used[start] {
            continue;
        }
        used[start] = true;
        let mut edges = vec![segments[start][0], segments[start][1]];
        // Extend at the back, then at the front.
        for front in [false, true] {
            loop {
                let end = if front {
                    edges[0]
                } else {
                    edges[edges.len() - 1]
                };
                let next = by_edge[end]
                    .iter()
                    .find(|&&s| s != NONE && !used[s as usize]);
                let Some(&s) = next else { break };
                used[s as usize] = true;
                let [a, b] = segments[s as usize];
                let other = if a == end { b } else { a };
                if front {
                    edges.insert(0, other);
                } else {
                    edges.push(other);
                }
            }
        }
        chains.push(edges.iter().map(|&e| crossing[e]).collect());
    }
    chains
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn circle_around_a_point_is_traced_as_one_closed_chain() {
        let field = DistanceField::new(&[Point2::new(5.0, 5.0)], 0.5, 20.0);
        let chains = trace_contours(&field, |_, d| d - 10.0);
        assert_eq!(chains.len(), 1);
        let c = &chains[0];
        assert!(c.len() > 100);
        assert!((c[0] - c[c.len() - 1]).norm() < 1e-9, "not closed");
        for p in c {
            let r = (p - Point2::new(5.0, 5.0)).norm();
            assert!((r - 10.0).abs() < 0.05, "{p} at {r}");
        }
        assert!((field.distance(Point2::new(8.0, 9.0)) - 5.0).abs() < 0.05);
        let dir = field.descent_direction(Point2::new(15.0, 5.0)).unwrap();
        assert!((dir - Vector2::new(-1.0, 0.0)).norm() < 1e-6);
    }
}
