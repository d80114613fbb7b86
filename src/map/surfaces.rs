//! A volume's boundaries as surfaces: the points of one type on neighbouring edges of the 3-D
//! grid (each slice's in-plane edges and the edges between slices, [`super::boundaries`])
//! joined into triangle meshes, one per sheet, and the places where sheets of two types meet
//! (codimension-two candidates).
//!
//! Each cube of eight neighbouring cells holds, for one sheet kind, the points on its twelve
//! edges; three or more are a polygon where the sheet crosses the cube (as in marching cubes,
//! but through the located points rather than interpolated ones): ordered by angle about
//! their centroid in their best-fitting plane (grid units, so that no axis dominates) and cut
//! into a fan of triangles. A point lies on the edges of up to four cubes and is one vertex of
//! all of them, so that the polygons of neighbouring cubes share it and the sheet is one mesh.

use std::collections::{BTreeMap, HashMap, HashSet};

use nalgebra::{Matrix3, Vector3};
use serde::Serialize;

use super::boundaries::{MapBoundaries, Point, Type};
use crate::config::Config;

/// What one sheet joins: a type and, for a located change, the class of the cycle that changes
/// (a period doubling of period-2 and one of period-4 are two sheets; a doubling seen from the
/// doubled side is its half's); for a coexistence the pair of classes.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
pub struct Kind {
    #[serde(rename = "type")]
    pub ty: TypeName,
    pub class: String,
}

/// A type by its name, ordered as [`Type::ALL`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct TypeName(pub usize);

impl TypeName {
    pub fn ty(self) -> Type {
        Type::ALL[self.0]
    }
}

impl Serialize for TypeName {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.ty().name())
    }
}

/// One connected mesh of one kind.
#[derive(Clone, Debug, Serialize)]
pub struct Sheet {
    #[serde(flatten)]
    pub kind: Kind,
    /// The period of the cycle that changes (0: none, a coexistence).
    pub period: u32,
    /// Indices into [`Surfaces::vertices`].
    #[serde(skip)]
    pub faces: Vec<[u32; 3]>,
    pub vertices: usize,
    pub triangles: usize,
    /// The sheet's extent in parameter values: (x, y, z) lows, then highs.
    pub lo: [f64; 3],
    pub hi: [f64; 3],
}

/// Where a sheet ends on a sheet of another type: the first sheet's rim (its mesh edges of one
/// triangle only) stops at a face of the grid's cubes, and the cube across that face (inside
/// the grid: a rim on the grid's outer face is the grid's end) holds a triangle of the second:
/// a candidate point of codimension two (a period-doubling sheet ending on a grazing sheet,
/// say), at the mean of the first sheet's rim points there.
#[derive(Clone, Debug, Serialize)]
pub struct Meeting {
    pub x: f64,
    pub y: f64,
    pub z: f64,
    /// The sheet that ends, then the one it ends on (their kinds, and their indices in
    /// [`Surfaces::sheets`]).
    pub kinds: [Kind; 2],
    pub sheets: [u32; 2],
}

/// The surfaces of a volume's boundaries.
#[derive(Clone, Debug, Serialize)]
pub struct Surfaces {
    pub x_param: &'static str,
    pub y_param: &'static str,
    pub z_param: &'static str,
    /// Every vertex in parameter values (x, y, z), with the sheet it belongs to.
    #[serde(skip)]
    pub vertices: Vec<([f64; 3], u32)>,
    pub sheets: Vec<Sheet>,
    pub codim2: Vec<Meeting>,
}

/// The axis of a grid edge.
const X: u8 = 0;
const Y: u8 = 1;
const Z: u8 = 2;

/// A point of the boundaries placed on its grid edge: (lower cell of the volume, axis).
type EdgeKey = (usize, u8);

/// The kind of sheet a point belongs to (`None`: not meshed: undetermined points, whose
/// reasons differ from edge to edge).
fn kind_of(p: &Point) -> Option<Kind> {
    let ty = TypeName(Type::ALL.iter().position(|&t| t == p.ty)?);
    match p.ty {
        Type::Undetermined => None,
        // A doubling seen from the doubled side (period-2n merging into period-n) is the
        // period-n cycle's doubling: one sheet whichever side it was continued from.
        Type::PeriodDoubling
            if p.located
                && p.change[1]
                    .strip_prefix("period-")
                    .and_then(|n| n.parse::<u32>().ok())
                    == Some(p.period / 2)
                && p.period.is_multiple_of(2) =>
        {
            Some(Kind {
                ty,
                class: p.change[1].clone(),
            })
        }
        _ if p.located => Some(Kind {
            ty,
            class: p.change[0].clone(),
        }),
        _ => {
            let mut c = p.classes.clone();
            c.sort();
            Some(Kind {
                ty,
                class: c.join("|"),
            })
        }
    }
}

/// Joins the points of `b` (the boundaries of the volume `cfg`) into sheets.
pub fn of(cfg: &Config, b: &MapBoundaries) -> Surfaces {
    let m = &cfg.map;
    let (nx, ny) = (m.x_points as usize, m.y_points as usize);
    let nz = cfg.z_count();
    let per = nx * ny;
    let z = cfg.z_axis();
    let zs = z.as_ref().map_or_else(|| vec![0.0], |z| z.values());
    // Every point with its grid edge and its coordinates.
    let mut placed: Vec<(EdgeKey, [f64; 3], &Point)> = Vec::new();
    for (k, s) in b.slices.iter().enumerate() {
        for p in &s.points {
            let (a, c) = (p.cells[0].min(p.cells[1]), p.cells[0].max(p.cells[1]));
            // (A grid one cell wide has y edges of one cell's step: tell y first.)
            let axis = if c - a == nx { Y } else { X };
            placed.push(((k * per + a, axis), [p.x, p.y, zs[k]], p));
        }
    }
    for p in b.across.iter().flat_map(|a| &a.points) {
        let a = p.cells[0].min(p.cells[1]);
        placed.push(((a, Z), [p.x, p.y, p.z.unwrap_or(f64::NAN)], p));
    }
    // Grid units: the cell index along each axis (from the cell centres' spacing).
    let axis = |from: f64, to: f64, n: usize| {
        let v = Config::map_axis(from, to, n as u32);
        let (v0, step) = (v[0], if n > 1 { v[1] - v[0] } else { 1.0 });
        move |x: f64| (x - v0) / step
    };
    let (gx, gy) = (axis(m.x_from, m.x_to, nx), axis(m.y_from, m.y_to, ny));
    let gz = z
        .as_ref()
        .map(|z| axis(z.from, z.to, nz))
        .unwrap_or_else(|| axis(0.0, 1.0, 1));
    let unit = |p: [f64; 3]| Vector3::new(gx(p[0]), gy(p[1]), gz(p[2]));
    // The first point of each kind on each edge (a second change of one kind on one edge
    // joins no sheet of its own).
    let mut by_kind: BTreeMap<Kind, HashMap<EdgeKey, usize>> = BTreeMap::new();
    for (i, (e, _, p)) in placed.iter().enumerate() {
        if let Some(k) = kind_of(p) {
            by_kind.entry(k).or_default().entry(*e).or_insert(i);
        }
    }
    // The twelve edges of the cube whose lowest cell is `c`.
    let cube_edges = |c: usize| -> [EdgeKey; 12] {
        let (dx, dy, dz) = (1, nx, per);
        [
            (c, X),
            (c + dy, X),
            (c + dz, X),
            (c + dy + dz, X),
            (c, Y),
            (c + dx, Y),
            (c + dz, Y),
            (c + dx + dz, Y),
            (c, Z),
            (c + dx, Z),
            (c + dy, Z),
            (c + dx + dy, Z),
        ]
    };
    let cubes = || {
        (0..nz.saturating_sub(1)).flat_map(move |iz| {
            (0..ny.saturating_sub(1)).flat_map(move |iy| {
                (0..nx.saturating_sub(1)).map(move |ix| (iz * ny + iy) * nx + ix)
            })
        })
    };
    // The cube across the face of cube `c` that holds both grid edges `e` and `f` (`None` where
    // that face is the grid's outer one); `c` itself where no face holds both.
    let across = |c: usize, e: EdgeKey, f: EdgeKey| -> Option<usize> {
        let at = |cell: usize| [cell % nx, (cell / nx) % ny, cell / per];
        let (n, step) = ([nx, ny, nz], [1, nx, per]);
        let c0 = at(c);
        let on = |(cell, axis): EdgeKey, d: usize, v: usize| {
            usize::from(axis) != d && at(cell)[d] == c0[d] + v
        };
        for d in 0..3 {
            for v in 0..2 {
                if on(e, d, v) && on(f, d, v) {
                    return match v {
                        0 if c0[d] > 0 => Some(c - step[d]),
                        1 if c0[d] + 2 < n[d] => Some(c + step[d]),
                        _ => None,
                    };
                }
            }
        }
        Some(c)
    };
    let mut vertices: Vec<([f64; 3], u32)> = Vec::new();
    let mut sheets = Vec::new();
    // For the meetings: each cube's sheets, and the rim points of each sheet that ends there.
    let mut passes: BTreeMap<usize, Vec<u32>> = BTreeMap::new();
    let mut rims: BTreeMap<usize, Vec<(u32, Vec<usize>)>> = BTreeMap::new();
    for (kind, on_edge) in &by_kind {
        let mut faces: Vec<[usize; 3]> = Vec::new();
        let mut face_cube: Vec<usize> = Vec::new();
        let mut seen: HashSet<[usize; 3]> = HashSet::new();
        for c in cubes() {
            let pts: Vec<usize> = cube_edges(c)
                .iter()
                .filter_map(|e| on_edge.get(e).copied())
                .collect();
            if pts.len() < 3 {
                continue;
            }
            for t in fan(&pts, &|i| unit(placed[i].1)) {
                let mut key = t;
                key.sort_unstable();
                if seen.insert(key) {
                    faces.push(t);
                    face_cube.push(c);
                }
            }
        }
        // Sheets: the connected parts of the kind's mesh (triangles sharing a vertex).
        for part in components(&faces) {
            let mut index: HashMap<usize, u32> = HashMap::new();
            let sheet = sheets.len() as u32;
            let mut sheet_faces = Vec::with_capacity(part.len());
            let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
            for &f in &part {
                let tri = faces[f].map(|i| {
                    *index.entry(i).or_insert_with(|| {
                        let at = placed[i].1;
                        for d in 0..3 {
                            lo[d] = lo[d].min(at[d]);
                            hi[d] = hi[d].max(at[d]);
                        }
                        vertices.push((at, sheet));
                        (vertices.len() - 1) as u32
                    })
                });
                sheet_faces.push(tri);
            }
            // The changing cycle's period (the class the sheet is keyed by).
            let period = kind
                .class
                .strip_prefix("period-")
                .and_then(|n| n.parse().ok())
                .unwrap_or(0);
            // The rim: mesh edges of one triangle only, by the cube beyond it (the rim's two
            // points lie on a face of the triangle's cube: the sheet stops at that face, and
            // what stops it lies in the cube across; a rim through a cube's inside, that cube).
            let mut uses: HashMap<(usize, usize), usize> = HashMap::new();
            for &f in &part {
                let t = faces[f];
                for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
                    *uses.entry((a.min(b), a.max(b))).or_default() += 1;
                }
            }
            for &f in &part {
                let (t, c) = (faces[f], face_cube[f]);
                passes.entry(c).or_default().push(sheet);
                for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
                    if uses[&(a.min(b), a.max(b))] == 1 {
                        let Some(beyond) = across(c, placed[a].0, placed[b].0) else {
                            continue;
                        };
                        let r = rims.entry(beyond).or_default();
                        match r.iter_mut().find(|(s, _)| *s == sheet) {
                            Some((_, pts)) => pts.extend([a, b]),
                            None => r.push((sheet, vec![a, b])),
                        }
                    }
                }
            }
            sheets.push(Sheet {
                kind: kind.clone(),
                period,
                vertices: index.len(),
                triangles: sheet_faces.len(),
                faces: sheet_faces,
                lo,
                hi,
            });
        }
    }
    for list in passes.values_mut() {
        list.sort_unstable();
        list.dedup();
    }
    // Bifurcations of two types; a coexistence is a basin's edge, not one.
    let bifurcation = |k: &Kind| k.ty.ty() != Type::Coexistence;
    let mut codim2 = Vec::new();
    for (c, rim) in &rims {
        for (a, pts) in rim {
            let ka = &sheets[*a as usize].kind;
            for &b in passes.get(c).into_iter().flatten() {
                let kb = &sheets[b as usize].kind;
                if ka.ty == kb.ty || !bifurcation(ka) || !bifurcation(kb) {
                    continue;
                }
                let mean =
                    |d: usize| pts.iter().map(|&i| placed[i].1[d]).sum::<f64>() / pts.len() as f64;
                codim2.push(Meeting {
                    x: mean(0),
                    y: mean(1),
                    z: mean(2),
                    kinds: [ka.clone(), kb.clone()],
                    sheets: [*a, b],
                });
            }
        }
    }
    Surfaces {
        x_param: m.x.name(),
        y_param: m.y.name(),
        z_param: z.map_or("", |z| z.param.name()),
        vertices,
        sheets,
        codim2,
    }
}

/// The triangles of the polygon through `pts` (`at`: a point's position in grid units):
/// ordered by angle about the centroid in the plane that fits them best, then a fan from the
/// first; triangles of no area (points in a line) left out.
fn fan(pts: &[usize], at: &dyn Fn(usize) -> Vector3<f64>) -> Vec<[usize; 3]> {
    let p: Vec<Vector3<f64>> = pts.iter().map(|&i| at(i)).collect();
    let c = p.iter().sum::<Vector3<f64>>() / p.len() as f64;
    let cov = p
        .iter()
        .map(|q| (q - c) * (q - c).transpose())
        .sum::<Matrix3<f64>>();
    let eig = cov.symmetric_eigen();
    let n = eig.eigenvalues.imin();
    let normal = eig.eigenvectors.column(n).into_owned();
    // Two directions in the plane.
    let u = (p[0] - c)
        .cross(&normal)
        .try_normalize(1e-12)
        .unwrap_or_else(|| normal.cross(&Vector3::x()).normalize());
    let v = normal.cross(&u);
    let mut order: Vec<usize> = (0..p.len()).collect();
    order.sort_by(|&a, &b| {
        let ang = |k: usize| (p[k] - c).dot(&v).atan2((p[k] - c).dot(&u));
        ang(a).total_cmp(&ang(b)).then(a.cmp(&b))
    });
    let mut out = Vec::new();
    for w in order[1..].windows(2) {
        let (a, b, d) = (p[order[0]], p[w[0]], p[w[1]]);
        if (b - a).cross(&(d - a)).norm() > 1e-9 {
            out.push([pts[order[0]], pts[w[0]], pts[w[1]]]);
        }
    }
    out
}

/// The faces of each connected part of the mesh `faces` (faces sharing a vertex), in order of
/// their first face.
fn components(faces: &[[usize; 3]]) -> Vec<Vec<usize>> {
    let mut parent: HashMap<usize, usize> = HashMap::new();
    fn find(parent: &mut HashMap<usize, usize>, v: usize) -> usize {
        let p = *parent.entry(v).or_insert(v);
        if p == v {
            return v;
        }
        let r = find(parent, p);
        parent.insert(v, r);
        r
    }
    for f in faces {
        let r = find(&mut parent, f[0]);
        for &v in &f[1..] {
            let s = find(&mut parent, v);
            parent.insert(s, r);
        }
    }
    let mut parts: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    let mut first: HashMap<usize, usize> = HashMap::new();
    for (i, f) in faces.iter().enumerate() {
        let r = find(&mut parent, f[0]);
        let at = *first.entry(r).or_insert(i);
        parts.entry(at).or_default().push(i);
    }
    parts.into_values().collect()
}

impl Surfaces {
    /// The meshes as one PLY file (ASCII): vertices in parameter values with their type code
    /// (the index in the comment's list), the changing cycle's period and their sheet; faces
    /// with the same three properties.
    pub fn ply(&self) -> String {
        let mut s = String::from("ply\nformat ascii 1.0\n");
        s.push_str(&format!(
            "comment rattle {} boundary surfaces: x = {}, y = {}, z = {}\n",
            env!("CARGO_PKG_VERSION"),
            self.x_param,
            self.y_param,
            self.z_param
        ));
        for (i, t) in Type::ALL.iter().enumerate() {
            s.push_str(&format!("comment type {i} = {}\n", t.name()));
        }
        let faces: usize = self.sheets.iter().map(|s| s.faces.len()).sum();
        s.push_str(&format!(
            "element vertex {}\nproperty double x\nproperty double y\nproperty double z\n\
             property uchar type\nproperty uint period\nproperty uint sheet\n\
             element face {faces}\nproperty list uchar uint vertex_indices\n\
             property uchar type\nproperty uint period\nproperty uint sheet\nend_header\n",
            self.vertices.len()
        ));
        for (at, sheet) in &self.vertices {
            let sh = &self.sheets[*sheet as usize];
            s.push_str(&format!(
                "{} {} {} {} {} {sheet}\n",
                at[0], at[1], at[2], sh.kind.ty.0, sh.period
            ));
        }
        for (k, sh) in self.sheets.iter().enumerate() {
            for f in &sh.faces {
                s.push_str(&format!(
                    "3 {} {} {} {} {} {k}\n",
                    f[0], f[1], f[2], sh.kind.ty.0, sh.period
                ));
            }
        }
        s
    }

    /// The vertices as CSV: sheet, type, changing class, period, x, y, z (named by the
    /// parameters).
    pub fn csv(&self) -> String {
        let mut s = format!(
            "sheet,type,class,period,{},{},{}\n",
            self.x_param, self.y_param, self.z_param
        );
        for (at, sheet) in &self.vertices {
            let sh = &self.sheets[*sheet as usize];
            s.push_str(&format!(
                "{sheet},{},{},{},{},{},{}\n",
                sh.kind.ty.ty().name(),
                sh.kind.class,
                sh.period,
                at[0],
                at[1],
                at[2]
            ));
        }
        s
    }
}

/// The least distance from `p` to the triangle `t` (in the units of their coordinates).
pub fn distance(p: [f64; 3], t: [[f64; 3]; 3]) -> f64 {
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let seg = |a: [f64; 3], b: [f64; 3]| {
        let (ab, ap) = (sub(b, a), sub(p, a));
        let s = (dot(ap, ab) / dot(ab, ab)).clamp(0.0, 1.0);
        let q = [a[0] + s * ab[0], a[1] + s * ab[1], a[2] + s * ab[2]];
        dot(sub(p, q), sub(p, q)).sqrt()
    };
    let (u, v, w) = (sub(t[1], t[0]), sub(t[2], t[0]), sub(p, t[0]));
    let (uu, uv, vv, wu, wv) = (dot(u, u), dot(u, v), dot(v, v), dot(w, u), dot(w, v));
    let det = uu * vv - uv * uv;
    let (s, r) = ((vv * wu - uv * wv) / det, (uu * wv - uv * wu) / det);
    if det > 0.0 && s >= 0.0 && r >= 0.0 && s + r <= 1.0 {
        let q: [f64; 3] = std::array::from_fn(|i| t[0][i] + s * u[i] + r * v[i]);
        return dot(sub(p, q), sub(p, q)).sqrt();
    }
    seg(t[0], t[1]).min(seg(t[1], t[2])).min(seg(t[2], t[0]))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A polygon of a plane's section of a cube: the fan covers it with n - 2 triangles of
    /// positive area, whatever the order the points come in.
    #[test]
    fn a_cubes_polygon_is_a_fan_of_its_points_in_order() {
        // The plane x + y + z = 1.5 meets the unit cube's edges in a hexagon.
        let hex = [
            [1.0, 0.5, 0.0],
            [0.0, 1.0, 0.5],
            [0.5, 0.0, 1.0],
            [1.0, 0.0, 0.5],
            [0.0, 0.5, 1.0],
            [0.5, 1.0, 0.0],
        ];
        let at = |i: usize| Vector3::from(hex[i]);
        let tris = fan(&[0, 1, 2, 3, 4, 5], &at);
        assert_eq!(tris.len(), 4);
        // A fan of a convex polygon in order: the triangles' areas sum to the regular
        // hexagon's, (3 sqrt 3 / 2) * side^2 with side sqrt(0.5) (out of order they overlap).
        let area: f64 = tris
            .iter()
            .map(|t| 0.5 * (at(t[1]) - at(t[0])).cross(&(at(t[2]) - at(t[0]))).norm())
            .sum();
        let want = 3.0 * 3f64.sqrt() / 2.0 * 0.5;
        assert!((area - want).abs() < 1e-12, "{area} against {want}");
    }

    /// A horizontal doubling sheet (between slices 1 and 2, over x cells 0-2) that stops at a
    /// vertical grazing sheet (between x cells 2 and 3, through the whole volume): each of the
    /// doubling sheet's rim segments along the grazing sheet is a meeting, and no other rim
    /// (those on the grid's outer faces, the grazing sheet's) is one.
    #[test]
    fn a_sheet_ending_on_another_is_a_meeting() {
        use crate::map::boundaries::{Boundaries, Point};
        use crate::model::Param;
        let n = 5usize;
        let mut cfg = Config::default();
        cfg.map.x_points = n as u32;
        cfg.map.y_points = n as u32;
        cfg.map.z = Some(Param::Eta);
        cfg.map.z_from = Some(1.0);
        cfg.map.z_to = Some(2.0);
        cfg.map.z_points = Some(n as u32);
        let m = &cfg.map;
        let xs = Config::map_axis(m.x_from, m.x_to, m.x_points);
        let ys = Config::map_axis(m.y_from, m.y_to, m.y_points);
        let zs = cfg.z_axis().unwrap().values();
        let point = |at: [f64; 3], z: Option<f64>, ty, class: &str, cells| Point {
            x: at[0],
            y: at[1],
            z,
            ty,
            classes: [class.into(), "chaotic".into()],
            change: [class.into(), "chaotic".into()],
            uncertainty: 0.0,
            located: true,
            period: 1,
            cells,
            from: Some(cells[0]),
            section: None,
            reason: "",
            evidence: String::new(),
            edge: 0,
            after_by_default: false,
        };
        let empty = |points| Boundaries {
            x_param: "R",
            y_param: "lambda",
            edges: 0,
            curves: Vec::new(),
            points,
            trials: 0,
            continuations: 0,
            claims: 0,
            continuation_s: 0.0,
            coexistence_s: 0.0,
            seconds: 0.0,
        };
        let per = n * n;
        // The grazing sheet: in every slice, the edges between x cells 2 and 3.
        let slices = (0..n)
            .map(|_| {
                empty(
                    (0..n)
                        .map(|iy| {
                            let a = iy * n + 2;
                            let at = [0.5 * (xs[2] + xs[3]), ys[iy], f64::NAN];
                            point(at, None, Type::Grazing, "period-2", [a, a + 1])
                        })
                        .collect(),
                )
            })
            .collect();
        // The doubling sheet: between slices 1 and 2 over x cells 0-2.
        let z = 0.5 * (zs[1] + zs[2]);
        let across = (0..n)
            .flat_map(|iy| (0..3).map(move |ix| (ix, iy)))
            .map(|(ix, iy)| {
                let a = per + iy * n + ix;
                let at = [xs[ix], ys[iy], z];
                point(at, Some(z), Type::PeriodDoubling, "period-1", [a, a + per])
            })
            .collect();
        let sf = of(
            &cfg,
            &MapBoundaries {
                slices,
                across: Some(empty(across)),
                slices_s: None,
            },
        );
        let kinds: Vec<(&str, &str)> = sf
            .sheets
            .iter()
            .map(|s| (s.kind.ty.ty().name(), &s.kind.class[..]))
            .collect();
        assert_eq!(
            kinds,
            [("period_doubling", "period-1"), ("grazing", "period-2")]
        );
        // One meeting per cube along y beside the grazing sheet, at x cell 2, between the slices.
        assert_eq!(sf.codim2.len(), n - 1, "{:?}", sf.codim2);
        for (k, c) in sf.codim2.iter().enumerate() {
            assert_eq!(c.sheets, [0, 1]);
            assert_eq!((c.x, c.z), (xs[2], z));
            assert!((c.y - 0.5 * (ys[k] + ys[k + 1])).abs() < 1e-12, "{c:?}");
        }
    }

    #[test]
    fn components_split_meshes_that_share_no_vertex() {
        let faces = [[0, 1, 2], [5, 6, 7], [2, 3, 4], [7, 8, 9], [10, 11, 12]];
        let parts = components(&faces);
        assert_eq!(parts, vec![vec![0, 2], vec![1, 3], vec![4]]);
    }
}
