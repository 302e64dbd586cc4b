//! Small meshes and derivative checks shared by the unit tests of the regularizers and design maps.

use crate::design_mesh::{DesignMesh, DesignPanel, DesignSeam};
use crate::math::{Real, Vec2, Vec3};
use crate::term::{Fabric, Residuals, Term, TermGradient, TermInput};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use skintight_geometry::finite_difference::{FdParams, check_gradient, check_jacobian};
use skintight_physics::{TensionFieldDensity, TensionFieldParams};

/// A fabric for [`TermInput`] (the regularizers do not read it).
pub fn fabric() -> Fabric {
    Fabric {
        density: TensionFieldDensity::new(2.0e5, 0.3, &TensionFieldParams::default())
            .expect("valid material"),
        thickness: 1e-3,
    }
}

/// A seeded random generator.
pub fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

/// `(x0, y0, x1, y1, …)`.
pub fn flatten(points: &[Vec2]) -> Vec<Real> {
    points.iter().flat_map(|p| [p.x, p.y]).collect()
}

/// Inverse of [`flatten`].
pub fn unflatten(values: &[Real]) -> Vec<Vec2> {
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

/// The term's value at `pattern` (no cloth dependence: the cloth is a dummy).
pub fn term_value(term: &dyn Term, mesh: &DesignMesh, pattern: &[Vec2]) -> Real {
    let fabric = fabric();
    let cloth = vec![Vec3::zeros(); mesh.num_cloth_vertices];
    let input = TermInput {
        mesh,
        cloth: &cloth,
        pattern,
        fabric: &fabric,
    };
    term.evaluate(&input, None).expect("evaluation").value
}

/// Checks the pattern gradient of `term` against central differences, that the cloth gradient stays
/// zero, that the gradient is added (not assigned), and that `per_element` sums to the value.
pub fn check_term_gradient(term: &dyn Term, mesh: &DesignMesh, pattern: &[Vec2]) {
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
    let analytic: Vec<Real> = flatten(
        &gradient
            .pattern
            .iter()
            .map(|g| g - offset)
            .collect::<Vec<_>>(),
    );
    let x = flatten(pattern);
    let f = |x: &[Real]| term_value(term, mesh, &unflatten(x));
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
    let fabric = fabric();
    let cloth = vec![Vec3::zeros(); mesh.num_cloth_vertices];
    let input = TermInput {
        mesh,
        cloth: &cloth,
        pattern,
        fabric: &fabric,
    };
    term.residuals(&input)
        .expect("a sum-of-squares term")
        .expect("residuals")
}

/// Checks `Σ r² = value` and the residuals' pattern Jacobian against central differences.
pub fn check_term_residuals(term: &dyn Term, mesh: &DesignMesh, pattern: &[Vec2]) {
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
    let g = |x: &[Real]| term_residuals(term, mesh, &unflatten(x)).values;
    let params = FdParams {
        step: 1e-6,
        rel_tol: 1e-6,
        abs_tol: 1e-10,
    };
    if let Err(e) = check_jacobian(g, &flatten(pattern), &jac, &params) {
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
