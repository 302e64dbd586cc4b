//! The library of named fabrics: the JSON files of `fabrics/` (one fabric each, documented in
//! `fabrics/README.md`), compiled into the program so that a scene's `garment.fabric.name` means the same
//! fabric on every machine. Curves are `[elongation, N/m]` as in [`FabricCurves`].

use serde::{Deserialize, Serialize};

use skintight_geometry::math::Real;

/// A fabric's test curves in its own frame: `[elongation, tension]` points, elongation dimensionless
/// (0.5 = 50 %), tension per unit rest width in N/m (a strip test's N per 50 mm × 20). Each curve rises
/// strictly from (0, 0); see `skintight_physics::tension_curve`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FabricCurves {
    /// Around the limb, across the grain line.
    pub course: Vec<[Real; 2]>,
    /// Along the grain line (the limb's length).
    pub wale: Vec<[Real; 2]>,
    /// Shear strain `C_cw` (dimensionless) against N/m.
    pub shear: Vec<[Real; 2]>,
}

/// The files of `fabrics/`, by name (the file's stem).
const FILES: [(&str, &str); 4] = [
    (
        "circular_knit_class1",
        include_str!("../../fabrics/circular_knit_class1.json"),
    ),
    (
        "power_net_class2",
        include_str!("../../fabrics/power_net_class2.json"),
    ),
    (
        "power_net_soft",
        include_str!("../../fabrics/power_net_soft.json"),
    ),
    (
        "sports_tricot",
        include_str!("../../fabrics/sports_tricot.json"),
    ),
];

/// One fabric of the library.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LibraryFabric {
    /// Its name (the file's stem).
    pub name: String,
    /// What knit it stands for.
    pub description: String,
    /// Where its curves come from, or `illustrative`.
    pub source: String,
    /// Thickness (m).
    pub thickness_m: Real,
    /// Course, wale and shear curves (N/m).
    pub curves: FabricCurves,
}

/// The names of the library's fabrics, sorted.
pub fn fabric_names() -> Vec<&'static str> {
    FILES.iter().map(|(n, _)| *n).collect()
}

/// The fabric named `name`, if the library has it.
pub fn named_fabric(name: &str) -> Option<LibraryFabric> {
    let (_, text) = FILES.iter().find(|(n, _)| *n == name)?;
    serde_json::from_str(text).ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_file_of_the_folder_is_listed_parses_and_is_a_valid_law() {
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/fabrics");
        let mut stems: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .filter_map(|e| {
                let p = e.unwrap().path();
                (p.extension()? == "json").then(|| p.file_stem().unwrap().to_string_lossy().into())
            })
            .collect();
        stems.sort();
        assert_eq!(stems, fabric_names());
        for name in fabric_names() {
            let text = FILES.iter().find(|(n, _)| *n == name).unwrap().1;
            let f: LibraryFabric = serde_json::from_str(text).unwrap();
            assert_eq!(f.name, name);
            assert!(!f.source.is_empty());
            skintight_physics::orthotropic_density::OrthotropicDensity::new(
                &f.curves.course,
                &f.curves.wale,
                &f.curves.shear,
                f.thickness_m,
            )
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        }
        // The pair of issue 46: course curves a factor of two apart, the rest equal.
        let (a, b) = (
            named_fabric("power_net_class2").unwrap(),
            named_fabric("power_net_soft").unwrap(),
        );
        for (p, q) in a.curves.course.iter().zip(&b.curves.course) {
            assert_eq!((p[0], p[1]), (q[0], 2.0 * q[1]));
        }
        assert_eq!(a.curves.wale, b.curves.wale);
        assert!(named_fabric("no_such_fabric").is_none());
    }
}
