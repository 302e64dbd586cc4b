//! Meshes the integration tests write as files: shapes that are not a standing body.

/// A closed UV sphere of radius `r` (m) as OBJ text (outward).
pub fn sphere_obj(r: f64) -> String {
    let (nu, nv) = (24, 12);
    let mut s = String::new();
    s.push_str(&format!("v 0 {r} 0\n"));
    for j in 1..nv {
        let t = std::f64::consts::PI * j as f64 / nv as f64;
        for i in 0..nu {
            let p = 2.0 * std::f64::consts::PI * i as f64 / nu as f64;
            s.push_str(&format!(
                "v {} {} {}\n",
                r * t.sin() * p.cos(),
                r * t.cos(),
                r * t.sin() * p.sin()
            ));
        }
    }
    s.push_str(&format!("v 0 {} 0\n", -r));
    let v = |j: usize, i: usize| 2 + (j - 1) * nu + i % nu;
    let bottom = 2 + (nv - 1) * nu;
    for i in 0..nu {
        s.push_str(&format!("f 1 {} {}\n", v(1, i + 1), v(1, i)));
        s.push_str(&format!(
            "f {bottom} {} {}\n",
            v(nv - 1, i),
            v(nv - 1, i + 1)
        ));
    }
    for j in 1..nv - 1 {
        for i in 0..nu {
            s.push_str(&format!(
                "f {} {} {} {}\n",
                v(j, i),
                v(j, i + 1),
                v(j + 1, i + 1),
                v(j + 1, i)
            ));
        }
    }
    s
}
