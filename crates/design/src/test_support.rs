//! The design crate's test fixtures, one meaning per name: a test fabric ([`fabric`]); small hand-built
//! garments ([`strip`], [`place`], [`icosphere`], [`cylinder`]) and the derivative checks of terms on the
//! cloth and the pattern ([`check_term_gradient`], [`check_term_residuals`] over [`flatten`]ed
//! `[x; X̄]`); small pattern meshes ([`grid_panel`], [`two_panel_mesh`], …) and the derivative checks of
//! terms on the pattern alone — the regularizers and design maps ([`check_pattern_gradient`],
//! [`check_pattern_residuals`] over [`flatten_pattern`]ed `X̄`, with a dummy cloth).

use crate::design_mesh::{DesignMesh, DesignPanel, DesignSeam};
use crate::math::{Mat2, Mat3, Mat3x2, Real, Vec2, Vec3};
use crate::term::{Fabric, Residuals, Term, TermGradient, TermInput};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use skintight_geometry::finite_difference::{FdParams, check_gradient, check_jacobian};
use skintight_physics::{TensionFieldDensity, TensionFieldParams};

/// Young's modulus of the test fabric (Pa).
pub const E: Real = 2.0e5;
/// Poisson's ratio of the test fabric.
pub const NU: Real = 0.3;
/// Thickness of the test fabric (m).
pub const THICKNESS: Real = 8.0e-4;

/// The test fabric ([`E`], [`NU`], [`THICKNESS`]); the regularizers do not read it.
pub fn fabric() -> Fabric {
    Fabric::isotropic(
        TensionFieldDensity::new(E, NU, &TensionFieldParams::default()).unwrap(),
        THICKNESS,
    )
}

/// Two rectangular panels of `nx × ny` squares of side `cell` (m), sewn along one long side: panel 0
/// covers `[0, nx·cell] × [0, ny·cell]` and panel 1 its mirror image below the seam line `y = 0` in a
/// common *layout* plane. Returns the mesh, the layout coordinates of every cloth vertex, and the layout
/// coordinates of every pattern vertex (the pattern positions before any rigid placement).
pub struct Strip {
    pub mesh: DesignMesh,
    pub cloth_layout: Vec<Vec2>,
    pub pattern_layout: Vec<Vec2>,
}

pub fn strip(nx: usize, ny: usize, cell: Real) -> Strip {
    let row = nx + 1;
    let per_panel = row * (ny + 1);
    let mut cloth_layout = Vec::new();
    let mut pattern_layout = Vec::new();
    let mut pattern_cloth_vertex = Vec::new();
    let mut pattern_panel = Vec::new();
    // Panel 0: cloth ids equal pattern ids.
    for j in 0..=ny {
        for i in 0..=nx {
            let p = Vec2::new(i as Real, j as Real) * cell;
            cloth_layout.push(p);
            pattern_layout.push(p);
            pattern_cloth_vertex.push(j * row + i);
            pattern_panel.push(0);
        }
    }
    // Panel 1: row 0 is the seam (shared cloth vertices), rows below are new cloth vertices.
    for j in 0..=ny {
        for i in 0..=nx {
            let p = Vec2::new(i as Real, -(j as Real)) * cell;
            pattern_layout.push(p);
            pattern_panel.push(1);
            if j == 0 {
                pattern_cloth_vertex.push(i);
            } else {
                pattern_cloth_vertex.push(cloth_layout.len());
                cloth_layout.push(p);
            }
        }
    }
    let mut cloth_triangles = Vec::new();
    let mut pattern_triangles = Vec::new();
    for panel in 0..2 {
        let first = panel * per_panel;
        for j in 0..ny {
            for i in 0..nx {
                let a = first + j * row + i;
                let (b, c, d) = (a + 1, a + row + 1, a + row);
                let tris = if panel == 0 {
                    [[a, b, c], [a, c, d]]
                } else {
                    [[a, c, b], [a, d, c]]
                };
                for t in tris {
                    pattern_triangles.push(t);
                    cloth_triangles.push(t.map(|v| pattern_cloth_vertex[v]));
                }
            }
        }
    }
    let id = |panel: usize, i: usize, j: usize| panel * per_panel + j * row + i;
    // Counter-clockwise loops; panel 0 starts along the seam (bottom row, left to right).
    let mut b0 = Vec::new();
    b0.extend((0..nx).map(|i| id(0, i, 0)));
    b0.extend((0..ny).map(|j| id(0, nx, j)));
    b0.extend((1..=nx).rev().map(|i| id(0, i, ny)));
    b0.extend((1..=ny).rev().map(|j| id(0, 0, j)));
    let mut borders0 = vec![None; b0.len()];
    borders0[..nx].fill(Some(1));
    // Panel 1 lies below y = 0: counter-clockwise runs along the seam from right to left.
    let mut b1 = Vec::new();
    b1.extend((1..=nx).rev().map(|i| id(1, i, 0)));
    b1.extend((0..ny).map(|j| id(1, 0, j)));
    b1.extend((0..nx).map(|i| id(1, i, ny)));
    b1.extend((1..=ny).rev().map(|j| id(1, nx, j)));
    let mut borders1 = vec![None; b1.len()];
    borders1[..nx].fill(Some(0));
    let panels = vec![
        DesignPanel {
            name: "front".into(),
            first_vertex: 0,
            num_vertices: per_panel,
            boundary: b0,
            boundary_borders: borders0,
        },
        DesignPanel {
            name: "back".into(),
            first_vertex: per_panel,
            num_vertices: per_panel,
            boundary: b1,
            boundary_borders: borders1,
        },
    ];
    let seams = vec![DesignSeam {
        panels: [0, 1],
        vertices: [
            (0..=nx).map(|i| id(0, i, 0)).collect(),
            (0..=nx).map(|i| id(1, i, 0)).collect(),
        ],
        closed: false,
    }];
    let mesh = DesignMesh {
        cloth_triangles,
        pattern_triangles,
        pattern_cloth_vertex,
        pattern_panel,
        panels,
        seams,
        num_cloth_vertices: cloth_layout.len(),
    };
    Strip {
        mesh,
        cloth_layout,
        pattern_layout,
    }
}

/// A random rotation of 3D space.
pub fn random_rotation(rng: &mut ChaCha8Rng) -> Mat3 {
    let axis = Vec3::new(
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
    );
    let axis = if axis.norm() > 1e-3 { axis } else { Vec3::x() };
    *nalgebra::Rotation3::new(axis.normalize() * rng.random_range(-3.0..3.0)).matrix()
}

/// A 3 × 2 deformation gradient with principal stretches `s1, s2` (dimensionless) along random
/// directions, embedded by a random rotation.
pub fn deformation(rng: &mut ChaCha8Rng, s1: Real, s2: Real) -> Mat3x2 {
    let angle: Real = rng.random_range(-3.0..3.0);
    let v = *nalgebra::Rotation2::new(angle).matrix();
    let stretch = v * Mat2::new(s1, 0.0, 0.0, s2) * v.transpose();
    let rot = random_rotation(rng);
    let embed = Mat3x2::new(1.0, 0.0, 0.0, 1.0, 0.0, 0.0);
    rot * embed * stretch
}

/// Cloth positions `F·X + t` over the layout plus `noise` (m, uniform per coordinate), and pattern
/// positions: panel 0 as laid out, panel 1 rotated by `angle` (rad) and shifted, each plus `noise`.
pub fn place(
    rng: &mut ChaCha8Rng,
    strip: &Strip,
    f: &Mat3x2,
    angle: Real,
    noise: Real,
) -> (Vec<Vec3>, Vec<Vec2>) {
    let jitter3 = |rng: &mut ChaCha8Rng| {
        Vec3::new(
            rng.random_range(-1.0..=1.0),
            rng.random_range(-1.0..=1.0),
            rng.random_range(-1.0..=1.0),
        ) * noise
    };
    let shift = Vec3::new(0.3, -0.2, 0.5);
    let cloth = strip
        .cloth_layout
        .iter()
        .map(|p| f * p + shift + jitter3(rng))
        .collect();
    let rot = nalgebra::Rotation2::new(angle);
    let pattern = strip
        .pattern_layout
        .iter()
        .zip(&strip.mesh.pattern_panel)
        .map(|(p, &panel)| {
            let j = Vec2::new(rng.random_range(-1.0..=1.0), rng.random_range(-1.0..=1.0)) * noise;
            if panel == 0 {
                p + j
            } else {
                rot * p + Vec2::new(0.4, -0.7) + j
            }
        })
        .collect();
    (cloth, pattern)
}

/// `[x; X̄]` flattened: `3·#Vc` cloth coordinates, then `2·#Vp` pattern coordinates.
pub fn flatten(cloth: &[Vec3], pattern: &[Vec2]) -> Vec<Real> {
    cloth
        .iter()
        .flat_map(|p| p.iter().copied())
        .chain(pattern.iter().flat_map(|p| p.iter().copied()))
        .collect()
}

pub fn unflatten(v: &[Real], num_cloth: usize) -> (Vec<Vec3>, Vec<Vec2>) {
    let cloth = (0..num_cloth)
        .map(|i| Vec3::new(v[3 * i], v[3 * i + 1], v[3 * i + 2]))
        .collect();
    let rest = &v[3 * num_cloth..];
    let pattern = (0..rest.len() / 2)
        .map(|i| Vec2::new(rest[2 * i], rest[2 * i + 1]))
        .collect();
    (cloth, pattern)
}

pub fn gradient_flat(g: &TermGradient) -> Vec<Real> {
    flatten(&g.cloth, &g.pattern)
}

/// Value of `term` at the flattened state `v`.
pub fn value_at(term: &dyn Term, mesh: &DesignMesh, fabric: &Fabric, v: &[Real]) -> Real {
    let (cloth, pattern) = unflatten(v, mesh.num_cloth_vertices);
    let input = TermInput {
        mesh,
        cloth: &cloth,
        pattern: &pattern,
        fabric,
    };
    term.evaluate(&input, None).unwrap().value
}

/// Evaluates `term` with its gradient, checks that the per-element values sum to the value, that the
/// gradient is added (not assigned), and compares the gradient with central differences. Returns the
/// value.
pub fn check_term_gradient(
    term: &dyn Term,
    mesh: &DesignMesh,
    fabric: &Fabric,
    cloth: &[Vec3],
    pattern: &[Vec2],
    params: &FdParams,
) -> Real {
    let input = TermInput {
        mesh,
        cloth,
        pattern,
        fabric,
    };
    let mut grad = TermGradient::zeros(mesh);
    let eval = term.evaluate(&input, Some(&mut grad)).unwrap();
    assert!(eval.value.is_finite() && eval.value >= 0.0);
    let sum: Real = eval.per_element.iter().sum();
    assert!(
        (sum - eval.value).abs() <= 1e-12 * eval.value.abs() + 1e-300,
        "per-element sum {sum} vs value {}",
        eval.value
    );
    assert_eq!(term.evaluate(&input, None).unwrap(), eval);
    // Evaluating again adds the same gradient once more.
    let mut twice = grad.clone();
    term.evaluate(&input, Some(&mut twice)).unwrap();
    let g = gradient_flat(&grad);
    let big = g.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    for (a, b) in gradient_flat(&twice).iter().zip(&g) {
        assert!(
            (a - 2.0 * b).abs() <= 1e-12 * big,
            "gradient not added: {a} vs 2 × {b}"
        );
    }
    assert!(g.iter().all(|v| v.is_finite()));
    let v = flatten(cloth, pattern);
    if let Err(m) = check_gradient(|v| value_at(term, mesh, fabric, v), &v, &g, params) {
        panic!("{}: gradient mismatch: {m}", term.name());
    }
    eval.value
}

/// Checks that the residuals' squares sum to the value and that their Jacobian matches central
/// differences. Returns the number of residuals.
pub fn check_term_residuals(
    term: &dyn Term,
    mesh: &DesignMesh,
    fabric: &Fabric,
    cloth: &[Vec3],
    pattern: &[Vec2],
    params: &FdParams,
) -> usize {
    let input = TermInput {
        mesh,
        cloth,
        pattern,
        fabric,
    };
    let value = term.evaluate(&input, None).unwrap().value;
    let res = term.residuals(&input).unwrap().unwrap();
    let sq: Real = res.values.iter().map(|r| r * r).sum();
    assert!(
        (sq - value).abs() <= 1e-11 * value + 1e-300,
        "{}: Σ r² = {sq} vs value {value}",
        term.name()
    );
    let (nc, np) = (mesh.num_cloth_vertices, mesh.num_pattern_vertices());
    let n = 3 * nc + 2 * np;
    let m = res.values.len();
    let mut jac = vec![0.0; m * n];
    for &(k, v, d) in &res.cloth_jacobian {
        for c in 0..3 {
            jac[k * n + 3 * v + c] += d[c];
        }
    }
    for &(k, v, d) in &res.pattern_jacobian {
        for c in 0..2 {
            jac[k * n + 3 * nc + 2 * v + c] += d[c];
        }
    }
    assert!(jac.iter().all(|v| v.is_finite()));
    if m == 0 {
        return 0;
    }
    let residuals_at = |v: &[Real]| {
        let (cloth, pattern) = unflatten(v, nc);
        let input = TermInput {
            mesh,
            cloth: &cloth,
            pattern: &pattern,
            fabric,
        };
        term.residuals(&input).unwrap().unwrap().values
    };
    if let Err(e) = check_jacobian(residuals_at, &flatten(cloth, pattern), &jac, params) {
        panic!("{}: residual Jacobian mismatch: {e}", term.name());
    }
    m
}

/// A closed sphere of radius `radius` (m): the workspace's one icosphere
/// (`skintight_geometry::test_meshes::icosphere`, an icosahedron subdivided `levels` times, vertices
/// projected on the sphere; triangles counter-clockwise from outside) as `(triangles, positions)`.
pub fn icosphere(radius: Real, levels: usize) -> (Vec<[usize; 3]>, Vec<Vec3>) {
    let mesh = skintight_geometry::test_meshes::icosphere(levels, radius);
    (mesh.faces, mesh.positions)
}

/// A cylinder of radius `radius` (m) about the z axis, `around` vertices around and `rows + 1` rings
/// over `height` (m), open at both ends, triangles counter-clockwise from outside; the diagonal of each
/// quad alternates when `alternate`, and every vertex is moved along the surface by up to `jitter` of the
/// spacing (both directions; the rings at the ends only around). Returns `(triangles, positions,
/// (angle, z) parameters)`.
pub fn cylinder(
    rng: &mut ChaCha8Rng,
    radius: Real,
    height: Real,
    around: usize,
    rows: usize,
    alternate: bool,
    jitter: Real,
) -> (Vec<[usize; 3]>, Vec<Vec3>, Vec<Vec2>) {
    let da = 2.0 * std::f64::consts::PI / around as Real;
    let dz = height / rows as Real;
    let mut params = Vec::new();
    for j in 0..=rows {
        for i in 0..around {
            let ja = rng.random_range(-1.0..=1.0) * jitter * da;
            let jz = if j == 0 || j == rows {
                0.0
            } else {
                rng.random_range(-1.0..=1.0) * jitter * dz
            };
            params.push(Vec2::new(i as Real * da + ja, j as Real * dz + jz));
        }
    }
    let pos = params
        .iter()
        .map(|p| Vec3::new(radius * p.x.cos(), radius * p.x.sin(), p.y))
        .collect();
    let id = |i: usize, j: usize| j * around + i % around;
    let mut faces = Vec::new();
    for j in 0..rows {
        for i in 0..around {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            if !alternate || (i + j) % 2 == 0 {
                faces.extend([[a, b, c], [a, c, d]]);
            } else {
                faces.extend([[a, b, d], [b, c, d]]);
            }
        }
    }
    (faces, pos, params)
}

/// A design mesh in which every cloth triangle is its own pattern piece: the pattern triangle is the
/// cloth triangle laid flat (same edge lengths) and scaled by `1/stretch`, so every triangle has the
/// isotropic stretch `stretch`. Returns the mesh and the `3 #F` pattern positions (m).
pub fn soup_design_mesh(
    triangles: &[[usize; 3]],
    cloth: &[Vec3],
    stretch: Real,
) -> (DesignMesh, Vec<Vec2>) {
    let mut pattern = Vec::new();
    let mut pattern_triangles = Vec::new();
    let mut pattern_cloth_vertex = Vec::new();
    for t in triangles {
        let [a, b, c] = t.map(|v| cloth[v]);
        let (e1, e2) = (b - a, c - a);
        let u = e1.normalize();
        let n = e1.cross(&e2).normalize();
        let w = n.cross(&u);
        let first = pattern.len();
        for p in [Vec3::zeros(), e1, e2] {
            pattern.push(Vec2::new(p.dot(&u), p.dot(&w)) / stretch);
        }
        pattern_triangles.push([first, first + 1, first + 2]);
        pattern_cloth_vertex.extend_from_slice(t);
    }
    let mesh = DesignMesh {
        cloth_triangles: triangles.to_vec(),
        pattern_triangles,
        pattern_panel: vec![0; pattern.len()],
        pattern_cloth_vertex,
        panels: vec![],
        seams: vec![],
        num_cloth_vertices: cloth.len(),
    };
    (mesh, pattern)
}

// Pattern meshes and the checks of terms on the pattern alone.

/// A seeded random generator.
pub fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

/// Pattern positions flattened: `(x0, y0, x1, y1, …)`.
pub fn flatten_pattern(points: &[Vec2]) -> Vec<Real> {
    points.iter().flat_map(|p| [p.x, p.y]).collect()
}

/// Inverse of [`flatten_pattern`].
pub fn unflatten_pattern(values: &[Real]) -> Vec<Vec2> {
    values
        .chunks_exact(2)
        .map(|c| Vec2::new(c[0], c[1]))
        .collect()
}

/// A `width × height` (m) grid of `nx × ny` cells split into triangles (counter-clockwise), its interior
/// vertices moved randomly by up to `jitter` cell sizes, and its counter-clockwise boundary loop.
/// Vertex `(i, j)` has id `j (nx + 1) + i`.
pub fn grid_panel(
    nx: usize,
    ny: usize,
    width: Real,
    height: Real,
    jitter: Real,
    seed: u64,
) -> (Vec<Vec2>, Vec<[usize; 3]>, Vec<usize>) {
    let mut r = rng(seed);
    let (hx, hy) = (width / nx as Real, height / ny as Real);
    let mut positions = Vec::new();
    for j in 0..=ny {
        for i in 0..=nx {
            let mut p = Vec2::new(i as Real * hx, j as Real * hy);
            if i > 0 && j > 0 && i < nx && j < ny {
                p.x += jitter * hx * r.random_range(-1.0..1.0);
                p.y += jitter * hy * r.random_range(-1.0..1.0);
            }
            positions.push(p);
        }
    }
    let id = |i: usize, j: usize| j * (nx + 1) + i;
    let mut triangles = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            triangles.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            triangles.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    let mut boundary = Vec::new();
    boundary.extend((0..nx).map(|i| id(i, 0)));
    boundary.extend((0..ny).map(|j| id(nx, j)));
    boundary.extend((1..=nx).rev().map(|i| id(i, ny)));
    boundary.extend((1..=ny).rev().map(|j| id(0, j)));
    (positions, triangles, boundary)
}

/// One panel with the given triangles and outer boundary loop, free everywhere; the cloth vertices are
/// the pattern vertices.
pub fn single_panel_mesh(
    num_vertices: usize,
    triangles: &[[usize; 3]],
    boundary: &[usize],
) -> DesignMesh {
    DesignMesh {
        cloth_triangles: triangles.to_vec(),
        pattern_triangles: triangles.to_vec(),
        pattern_cloth_vertex: (0..num_vertices).collect(),
        pattern_panel: vec![0; num_vertices],
        panels: vec![DesignPanel {
            name: "panel".into(),
            first_vertex: 0,
            num_vertices,
            boundary: boundary.to_vec(),
            boundary_borders: vec![None; boundary.len()],
        }],
        seams: Vec::new(),
        num_cloth_vertices: num_vertices,
    }
}

/// A convex polygon (counter-clockwise `corners`, m) as one panel: the corners form the boundary loop
/// (ids `0..n`), and a centre vertex (id `n`) fans the triangles.
pub fn polygon_panel(corners: &[Vec2]) -> (DesignMesh, Vec<Vec2>) {
    let n = corners.len();
    let centre = corners.iter().sum::<Vec2>() / n as Real;
    let mut positions = corners.to_vec();
    positions.push(centre);
    let triangles: Vec<[usize; 3]> = (0..n).map(|i| [i, (i + 1) % n, n]).collect();
    let boundary: Vec<usize> = (0..n).collect();
    (single_panel_mesh(n + 1, &triangles, &boundary), positions)
}

/// Two `nx × ny` grid panels side by side (each `0.3 × 0.4` m, interior jittered), the right side of panel
/// 0 sewn to the left side of panel 1 (an open seam of `ny + 1` vertices).
pub fn two_panel_mesh(nx: usize, ny: usize, seed: u64) -> (DesignMesh, Vec<Vec2>) {
    let (w, h) = (0.3, 0.4);
    let (pos0, tri, boundary) = grid_panel(nx, ny, w, h, 0.25, seed);
    let (pos1, _, _) = grid_panel(nx, ny, w, h, 0.25, seed + 1);
    let nv = pos0.len();
    let id = |i: usize, j: usize| j * (nx + 1) + i;
    let mut pattern = pos0.clone();
    pattern.extend(pos1.iter().map(|p| p + Vec2::new(w + 0.1, 0.0)));
    // Cloth ids: panel 0 keeps its ids; panel 1's left column is panel 0's right column.
    let mut cloth_of = (0..nv).collect::<Vec<_>>();
    let mut next = nv;
    for j in 0..=ny {
        for i in 0..=nx {
            if i == 0 {
                cloth_of.push(id(nx, j));
            } else {
                cloth_of.push(next);
                next += 1;
            }
        }
    }
    let mut pattern_triangles = tri.clone();
    pattern_triangles.extend(tri.iter().map(|t| t.map(|v| v + nv)));
    let cloth_triangles = pattern_triangles
        .iter()
        .map(|t| t.map(|v| cloth_of[v]))
        .collect();
    let mut borders0 = vec![None; boundary.len()];
    for j in 0..ny {
        borders0[nx + j] = Some(1);
    }
    let mut borders1 = vec![None; boundary.len()];
    for k in 0..ny {
        borders1[2 * nx + ny + k] = Some(0);
    }
    let mesh = DesignMesh {
        cloth_triangles,
        pattern_triangles,
        pattern_cloth_vertex: cloth_of,
        pattern_panel: [vec![0; nv], vec![1; nv]].concat(),
        panels: vec![
            DesignPanel {
                name: "left".into(),
                first_vertex: 0,
                num_vertices: nv,
                boundary: boundary.clone(),
                boundary_borders: borders0,
            },
            DesignPanel {
                name: "right".into(),
                first_vertex: nv,
                num_vertices: nv,
                boundary: boundary.iter().map(|v| v + nv).collect(),
                boundary_borders: borders1,
            },
        ],
        seams: vec![DesignSeam {
            panels: [0, 1],
            vertices: [
                (0..=ny).map(|j| id(nx, j)).collect(),
                (0..=ny).map(|j| nv + id(0, j)).collect(),
            ],
            closed: false,
        }],
        num_cloth_vertices: next,
    };
    (mesh, pattern)
}

/// `points` each moved by a uniform random vector of up to `amount` (m) per coordinate.
pub fn perturbed(points: &[Vec2], amount: Real, seed: u64) -> Vec<Vec2> {
    let mut r = rng(seed);
    points
        .iter()
        .map(|p| {
            p + Vec2::new(
                amount * r.random_range(-1.0..1.0),
                amount * r.random_range(-1.0..1.0),
            )
        })
        .collect()
}

/// The term's value at `pattern` (no cloth dependence: the cloth is a dummy, the fabric [`fabric`]).
pub fn term_value(term: &dyn Term, mesh: &DesignMesh, pattern: &[Vec2]) -> Real {
    try_evaluate(term, mesh, pattern, None)
        .expect("evaluation")
        .value
}

/// For a term on the pattern alone (a regularizer): checks its pattern gradient against central
/// differences, that the cloth gradient stays zero, that the gradient is added (not assigned), and that `per_element` sums to the value.
pub fn check_pattern_gradient(term: &dyn Term, mesh: &DesignMesh, pattern: &[Vec2]) {
    let fabric = fabric();
    let cloth = vec![Vec3::zeros(); mesh.num_cloth_vertices];
    let input = TermInput {
        mesh,
        cloth: &cloth,
        pattern,
        fabric: &fabric,
    };
    let mut gradient = TermGradient::zeros(mesh);
    let offset = Vec2::new(0.25, -0.5);
    gradient.pattern.iter_mut().for_each(|g| *g = offset);
    let eval = term
        .evaluate(&input, Some(&mut gradient))
        .expect("evaluation");
    assert!(eval.value.is_finite());
    let total: Real = eval.per_element.iter().sum();
    assert!(
        (total - eval.value).abs() <= 1e-12 * eval.value.abs().max(1e-300),
        "per_element sums to {total}, value {}",
        eval.value
    );
    assert!(gradient.cloth.iter().all(|g| *g == Vec3::zeros()));
    let analytic: Vec<Real> = flatten_pattern(
        &gradient
            .pattern
            .iter()
            .map(|g| g - offset)
            .collect::<Vec<_>>(),
    );
    let x = flatten_pattern(pattern);
    let f = |x: &[Real]| term_value(term, mesh, &unflatten_pattern(x));
    let params = FdParams {
        step: 1e-6,
        rel_tol: 1e-6,
        abs_tol: 1e-9 * eval.value.abs().max(1e-12),
    };
    if let Err(e) = check_gradient(f, &x, &analytic, &params) {
        panic!("{}: {e}", term.name());
    }
}

/// The term's residuals at `pattern`.
pub fn term_residuals(term: &dyn Term, mesh: &DesignMesh, pattern: &[Vec2]) -> Residuals {
    try_residuals(term, mesh, pattern)
        .expect("a sum-of-squares term")
        .expect("residuals")
}

/// For a term on the pattern alone: checks `Σ r² = value` and the residuals' pattern Jacobian against
/// central differences.
pub fn check_pattern_residuals(term: &dyn Term, mesh: &DesignMesh, pattern: &[Vec2]) {
    let value = term_value(term, mesh, pattern);
    let res = term_residuals(term, mesh, pattern);
    let sum: Real = res.values.iter().map(|r| r * r).sum();
    assert!(
        (sum - value).abs() <= 1e-12 * value.abs().max(1e-300),
        "Σ r² = {sum}, value {value}"
    );
    assert!(res.cloth_jacobian.is_empty());
    let n = 2 * pattern.len();
    let m = res.values.len();
    let mut jac = vec![0.0; m * n];
    for &(k, v, d) in &res.pattern_jacobian {
        jac[k * n + 2 * v] += d.x;
        jac[k * n + 2 * v + 1] += d.y;
    }
    let g = |x: &[Real]| term_residuals(term, mesh, &unflatten_pattern(x)).values;
    let params = FdParams {
        step: 1e-6,
        rel_tol: 1e-6,
        abs_tol: 1e-10,
    };
    if let Err(e) = check_jacobian(g, &flatten_pattern(pattern), &jac, &params) {
        panic!("{} residuals: {e}", term.name());
    }
}

/// The term's evaluation at `pattern` (a dummy cloth), adding into `gradient` when given.
pub fn try_evaluate(
    term: &dyn Term,
    mesh: &DesignMesh,
    pattern: &[Vec2],
    gradient: Option<&mut TermGradient>,
) -> Result<crate::term::TermEvaluation, crate::term::TermError> {
    let fabric = fabric();
    let cloth = vec![Vec3::zeros(); mesh.num_cloth_vertices];
    let input = TermInput {
        mesh,
        cloth: &cloth,
        pattern,
        fabric: &fabric,
    };
    term.evaluate(&input, gradient)
}

/// The term's residuals at `pattern` (a dummy cloth), `None` for a term that is not a sum of squares.
pub fn try_residuals(
    term: &dyn Term,
    mesh: &DesignMesh,
    pattern: &[Vec2],
) -> Option<Result<Residuals, crate::term::TermError>> {
    let fabric = fabric();
    let cloth = vec![Vec3::zeros(); mesh.num_cloth_vertices];
    let input = TermInput {
        mesh,
        cloth: &cloth,
        pattern,
        fabric: &fabric,
    };
    term.residuals(&input)
}
