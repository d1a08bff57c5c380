//! Tests of the procedural meshes: volumes and their convergence, element
//! quality on every level, faces, gradings and fibre directions.

use super::*;
use std::collections::HashSet;

fn rate(coarse: f64, fine: f64) -> f64 {
    (coarse / fine).log2()
}

/// The rim classification and distances agree with the geometry: an
/// element touching a rim lies within its own size of it, the element
/// nearest a rim touches one, and the axis elements at mid-length lie
/// about √((L/2)² + R²) away (a cylinder, radius R, length L).
#[test]
fn end_rim_distances_follow_the_geometry() {
    let (length, radius) = (0.05, 0.01);
    let m = cylinder(length, radius, 8, 2);
    let touching = m.at_an_end_rim();
    let distances = m.end_rim_distances();
    assert!(touching.iter().any(|&t| t) && !touching.iter().all(|&t| t));
    for (e, (&t, &d)) in touching.iter().zip(&distances).enumerate() {
        let p = m.tet_points(e);
        let size = (0..4)
            .flat_map(|i| (0..4).map(move |j| (i, j)))
            .map(|(i, j)| (p[i] - p[j]).norm())
            .fold(0.0, f64::max);
        assert!(d >= 0.0 && d <= (0.5 * length).hypot(radius));
        if t {
            assert!(
                d < size,
                "element {e} touches a rim at distance {d} > {size}"
            );
        }
    }
    let nearest = (0..distances.len())
        .min_by(|&a, &b| distances[a].total_cmp(&distances[b]))
        .unwrap();
    assert!(touching[nearest]);
    let farthest = distances.iter().cloned().fold(0.0, f64::max);
    let expected = (0.5 * length).hypot(radius);
    assert!(farthest > 0.9 * expected, "{farthest} vs {expected}");
}

/// Composite Simpson on [0, L] with `n` (even) intervals.
fn simpson(f: impl Fn(f64) -> f64, length: f64, n: usize) -> f64 {
    let h = length / n as f64;
    let inner: f64 = (1..n)
        .map(|i| f(i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 })
        .sum();
    h / 3.0 * (f(0.0) + f(length) + inner)
}

#[test]
fn closed_form_volume_matches_quadrature() {
    for p in [
        Fusiform::PAPER,
        Fusiform {
            length: 1.0,
            r_end: 0.1,
            r_mid: 0.3,
        },
        Fusiform {
            length: 2.5,
            r_end: 0.4,
            r_mid: 0.2,
        },
        Fusiform::cylinder(0.03, 0.01),
    ] {
        let quad = simpson(|x| PI * p.radius(x).powi(2), p.length, 4000);
        let closed = p.volume();
        assert!(
            (closed - quad).abs() <= 1e-12 * closed,
            "{p:?}: {closed} vs {quad}"
        );
    }
    let c = Fusiform::cylinder(0.03, 0.01);
    assert!((c.volume() - PI * 1e-4 * 0.03).abs() < 1e-18);
    assert_eq!(
        DEFAULT_VOLUME,
        fusiform_volume(DEFAULT_LENGTH, DEFAULT_END_RADIUS, DEFAULT_MID_RADIUS)
    );
    assert_eq!(DEFAULT_MEAN_AREA, Fusiform::PAPER.mean_area());
    assert!((DEFAULT_VOLUME - 8.4245e-6).abs() < 1e-9);
    assert!((DEFAULT_MEAN_AREA - 1.6849e-4).abs() < 1e-8);
}

#[test]
fn profile_endpoints_and_slope() {
    let p = Fusiform::PAPER;
    assert!((p.radius(0.0) - DEFAULT_END_RADIUS).abs() < 1e-18);
    assert!((p.radius(p.length) - DEFAULT_END_RADIUS).abs() < 1e-17);
    assert!((p.radius(p.length / 2.0) - DEFAULT_MID_RADIUS).abs() < 1e-18);
    assert!(p.slope(p.length / 2.0).abs() < 1e-16);
    let h = 1e-7;
    for x in [0.0, 0.01, 0.02, 0.033, 0.05] {
        let fd = (p.radius(x + h) - p.radius(x - h)) / (2.0 * h);
        assert!((fd - p.slope(x)).abs() < 1e-8, "slope at {x}");
    }
}

#[test]
fn unit_disc_triangulation() {
    for n in 1..=6 {
        let (pts, tris) = unit_disc(n);
        assert_eq!(pts.len(), 1 + 3 * n * (n + 1));
        assert_eq!(tris.len(), 6 * n * n);
        let mut area = 0.0;
        for t in &tris {
            let a = (pts[t[1]] - pts[t[0]]).perp(&(pts[t[2]] - pts[t[0]])) / 2.0;
            assert!(a > 0.0, "triangle {t:?} not counter-clockwise");
            area += a;
        }
        // Exactly the inscribed regular 6n-gon.
        let m = 6.0 * n as f64;
        assert!((area - m / 2.0 * (2.0 * PI / m).sin()).abs() < 1e-13);
        // The six triangles at the centre are equilateral.
        for t in tris.iter().filter(|t| t.contains(&0)) {
            let e = [
                pts[t[0]] - pts[t[1]],
                pts[t[1]] - pts[t[2]],
                pts[t[2]] - pts[t[0]],
            ];
            for v in e {
                assert!((v.norm() - 1.0 / n as f64).abs() < 1e-14);
            }
        }
    }
}

#[test]
fn counts_and_end_faces() {
    for res in LEVELS.iter().copied().chain([
        Resolution {
            n_axial: 1,
            n_radial: 1,
        },
        Resolution {
            n_axial: 3,
            n_radial: 5,
        },
        Resolution {
            n_axial: 7,
            n_radial: 1,
        },
    ]) {
        let m = revolve(&Fusiform::PAPER, res, FibreLayout::Axial);
        let nps = res.nodes_per_slice();
        assert_eq!(m.nodes.len(), res.nodes());
        assert_eq!(m.tets.len(), res.tets());
        assert_eq!(m.tets.len(), 18 * res.n_radial * res.n_radial * res.n_axial);
        assert_eq!(m.fibre.len(), m.tets.len());
        assert_eq!(m.fixed_face.len(), nps);
        assert_eq!(m.moved_face.len(), nps);
        assert!(m.fixed_face.iter().all(|&n| m.nodes[n].x == 0.0));
        assert!(m.moved_face.iter().all(|&n| m.nodes[n].x == DEFAULT_LENGTH));
        let on_ends = m
            .nodes
            .iter()
            .filter(|p| p.x == 0.0 || p.x == DEFAULT_LENGTH)
            .count();
        assert_eq!(on_ends, 2 * nps);
        // Face nodes lie within the end disc, the outer ring on its circle.
        for &n in m.fixed_face.iter().chain(&m.moved_face) {
            let rho = (m.nodes[n].y.powi(2) + m.nodes[n].z.powi(2)).sqrt();
            assert!(rho <= DEFAULT_END_RADIUS * (1.0 + 1e-14));
        }
        // Every node is used, every tet has 4 distinct nodes.
        let mut used = vec![false; m.nodes.len()];
        for t in &m.tets {
            let set: HashSet<_> = t.iter().collect();
            assert_eq!(set.len(), 4);
            t.iter().for_each(|&n| used[n] = true);
        }
        assert!(used.iter().all(|&u| u));
    }
}

#[test]
fn graded_slices_are_monotone_symmetric_and_thin_at_the_ends() {
    let (n, l) = (12, 0.05);
    for beta in [0.0, 0.5, 0.85, MAX_GRADING] {
        let x: Vec<f64> = (0..=n).map(|s| graded_slice(s, n, l, beta)).collect();
        assert_eq!((x[0], x[n]), (0.0, l));
        assert!(x.windows(2).all(|w| w[1] > w[0]), "β {beta}: {x:?}");
        for s in 0..=n {
            assert!(
                (x[s] + x[n - s] - l).abs() < 1e-15,
                "β {beta}: not symmetric"
            );
        }
        // End layer ≈ (1 − β) L/n (to second order in 1/n), middle
        // layers ≈ (1 + β) L/n.
        let uniform = l / n as f64;
        let first = x[1] / uniform;
        assert!(
            (first - (1.0 - beta)).abs() < 0.05,
            "β {beta}: first layer {first}"
        );
        let middle = (x[n / 2 + 1] - x[n / 2]) / uniform;
        assert!(
            (middle - (1.0 + beta)).abs() < 0.05,
            "β {beta}: middle {middle}"
        );
    }
    // Rings: from the axis to the surface, increasing; the spacing
    // 1 + g (1 − 2u) in between; the disc's points on their rings.
    for g in [0.0, 0.5, 0.8, MAX_GRADING] {
        for n in [1, 3, 8] {
            let rho: Vec<f64> = (0..=n).map(|i| graded_ring(i, n, g)).collect();
            assert_eq!((rho[0], rho[n]), (0.0, 1.0));
            assert!(rho.windows(2).all(|w| w[1] > w[0]), "g {g}: {rho:?}");
            for i in 0..n {
                let (u0, u1) = (i as f64 / n as f64, (i + 1) as f64 / n as f64);
                let mean_spacing = 1.0 + g * (1.0 - (u0 + u1));
                let width = (rho[i + 1] - rho[i]) * n as f64;
                assert!(
                    (width - mean_spacing).abs() < 1e-14,
                    "g {g}, ring {i}: {width}"
                );
            }
            let (points, triangles) = unit_disc_graded(n, g);
            assert_eq!(triangles, unit_disc(n).1);
            for i in 1..=n {
                let first = 1 + 3 * i * (i - 1);
                for p in &points[first..first + 6 * i] {
                    assert!((p.norm() - rho[i]).abs() < 1e-15);
                }
            }
        }
    }
    // The graded default mesh: every tetrahedron positive, volume as the
    // uniform mesh's to the profile's discretization error.
    let res = Resolution {
        n_axial: 12,
        n_radial: 2,
    };
    let uniform = revolve_with(
        &Fusiform::PAPER,
        res,
        FibreLayout::Axial,
        Section::EqualArea,
    );
    let graded = revolve_graded(
        &Fusiform::PAPER,
        res,
        FibreLayout::Axial,
        Section::EqualArea,
        Grading::axial(0.85),
    );
    assert!(graded.element_volumes().iter().all(|&v| v > 0.0));
    let exact = Fusiform::PAPER.volume();
    assert!(((graded.volume() - exact) / exact).abs() < 0.02);
    assert!(((uniform.volume() - exact) / exact).abs() < 0.02);
    // Grading the rings moves no point of a slice's outer polygon, so the
    // volume is the same.
    for radial in [0.5, MAX_GRADING] {
        let both = revolve_graded(
            &Fusiform::PAPER,
            res,
            FibreLayout::Axial,
            Section::EqualArea,
            Grading {
                axial: 0.85,
                radial,
            },
        );
        assert!(both.element_volumes().iter().all(|&v| v > 0.0));
        assert!(((both.volume() - graded.volume()) / exact).abs() < 1e-14);
    }
}

#[test]
fn all_tets_positive_and_well_shaped() {
    // Quality bounds for every level, both sections; measured minima:
    // radius ratio 0.44–0.51, dihedral angles 20.3°–135.5° (docs/fe.md).
    const MIN_RADIUS_RATIO: f64 = 0.4;
    const MIN_DIHEDRAL_DEG: f64 = 18.0;
    const MAX_DIHEDRAL_DEG: f64 = 140.0;
    for res in LEVELS {
        for section in [Section::Inscribed, Section::EqualArea] {
            let m = revolve_with(&Fusiform::PAPER, res, FibreLayout::Axial, section);
            for (e, v) in m.element_volumes().iter().enumerate() {
                assert!(*v > 0.0, "{res:?}: tet {e} has volume {v}");
            }
            let (q_lo, q_hi) = m.radius_ratio_range();
            let (d_lo, d_hi) = m.dihedral_range();
            assert!(
                q_lo > MIN_RADIUS_RATIO && q_hi <= 1.0,
                "{res:?}: radius ratio {q_lo}"
            );
            assert!(
                d_lo.to_degrees() > MIN_DIHEDRAL_DEG,
                "{res:?}: dihedral {d_lo}"
            );
            assert!(
                d_hi.to_degrees() < MAX_DIHEDRAL_DEG,
                "{res:?}: dihedral {d_hi}"
            );
        }
    }
    // The measures themselves: 1 and acos(1/3) for the regular tetrahedron.
    let regular = [
        Vector3::new(1.0, 1.0, 1.0),
        Vector3::new(1.0, -1.0, -1.0),
        Vector3::new(-1.0, 1.0, -1.0),
        Vector3::new(-1.0, -1.0, 1.0),
    ];
    assert!((tet_radius_ratio(&regular) - 1.0).abs() < 1e-14);
    for a in tet_dihedral_angles(&regular) {
        assert!((a - (1.0f64 / 3.0).acos()).abs() < 1e-14);
    }
    let flat = [
        Vector3::zeros(),
        Vector3::x(),
        Vector3::y(),
        Vector3::new(0.3, 0.3, 1e-9),
    ];
    assert!(tet_radius_ratio(&flat) < 1e-8);
    // Any resolution gives positive elements, even badly stretched ones.
    for (na, nr) in [(1, 1), (1, 6), (40, 1), (5, 3), (8, 2)] {
        let m = fusiform(na, nr, FibreLayout::Axial);
        assert!(m.element_volumes().iter().all(|&v| v > 0.0), "({na}, {nr})");
    }
}

#[test]
fn conforming_with_expected_boundary() {
    for res in LEVELS.iter().take(4).copied().chain([
        Resolution {
            n_axial: 1,
            n_radial: 1,
        },
        Resolution {
            n_axial: 3,
            n_radial: 5,
        },
        Resolution {
            n_axial: 7,
            n_radial: 1,
        },
    ]) {
        let m = revolve(&Fusiform::PAPER, res, FibreLayout::Axial);
        let nps = res.nodes_per_slice();
        let outer_start = 1 + 3 * res.n_radial * (res.n_radial - 1);
        // Face multiplicities: 1 (boundary) or 2 (interior), never more.
        let mut count: HashMap<[usize; 3], usize> = HashMap::new();
        for t in &m.tets {
            for skip in 0..4 {
                let mut f = [0; 3];
                let mut k = 0;
                for (i, &n) in t.iter().enumerate() {
                    if i != skip {
                        f[k] = n;
                        k += 1;
                    }
                }
                f.sort_unstable();
                *count.entry(f).or_default() += 1;
            }
        }
        assert!(count.values().all(|&c| c == 1 || c == 2));
        let boundary = m.boundary_faces();
        assert_eq!(boundary.len(), count.values().filter(|&&c| c == 1).count());
        assert_eq!(boundary.len(), res.boundary_faces(), "{res:?}");
        assert_eq!(count.len(), (4 * m.tets.len() + boundary.len()) / 2);
        // Classify: end discs and lateral surface, with the expected counts.
        let (mut fixed, mut moved, mut lateral) = (0, 0, 0);
        for f in &boundary {
            if f.iter().all(|&n| n < nps) {
                fixed += 1;
            } else if f.iter().all(|&n| n >= res.n_axial * nps) {
                moved += 1;
            } else {
                assert!(
                    f.iter().all(|&n| n % nps >= outer_start),
                    "{f:?} is not on the surface"
                );
                lateral += 1;
            }
        }
        assert_eq!(fixed, res.triangles_per_slice());
        assert_eq!(moved, res.triangles_per_slice());
        assert_eq!(lateral, 12 * res.n_radial * res.n_axial);
        // Closed, consistently oriented surface: the divergence theorem
        // (1/3) Σ c·n A over the boundary gives back the volume.
        let flux: f64 = boundary
            .iter()
            .map(|f| {
                let p = f.map(|n| m.nodes[n]);
                let area_normal = (p[1] - p[0]).cross(&(p[2] - p[0])) / 2.0;
                ((p[0] + p[1] + p[2]) / 3.0).dot(&area_normal) / 3.0
            })
            .sum();
        assert!(
            (flux - m.volume()).abs() < 1e-12 * m.volume(),
            "{flux} vs {}",
            m.volume()
        );
        // Euler characteristic of a ball: V − E + F − T = 1.
        let mut edges = HashSet::new();
        for t in &m.tets {
            for i in 0..4 {
                for j in i + 1..4 {
                    edges.insert((t[i].min(t[j]), t[i].max(t[j])));
                }
            }
        }
        let chi =
            m.nodes.len() as i64 - edges.len() as i64 + count.len() as i64 - m.tets.len() as i64;
        assert_eq!(chi, 1);
    }
}

#[test]
fn volume_converges_at_second_order() {
    let v0 = DEFAULT_VOLUME;
    let errors: Vec<f64> = [(12, 2), (24, 4), (48, 8), (96, 16)]
        .iter()
        .map(|&(na, nr)| {
            let v = fusiform(na, nr, FibreLayout::Axial).volume();
            assert!(v < v0, "inscribed mesh must be smaller");
            (v0 - v) / v0
        })
        .collect();
    assert!(errors[0] < 0.06);
    for w in errors.windows(2) {
        let r = rate(w[0], w[1]);
        assert!((1.95..2.05).contains(&r), "rate {r}, errors {errors:?}");
    }
}

#[test]
fn radial_error_is_the_inscribed_polygon() {
    // A cylinder has no axial error: the mesh is the prism over the 6n-gon.
    let (l, r0) = (0.05, 0.01);
    let exact = PI * r0 * r0 * l;
    let mut errors = vec![];
    for n in [2, 4, 8, 16] {
        let v = cylinder(l, r0, 3, n).volume();
        let m = 6.0 * n as f64;
        let polygon = m / 2.0 * (2.0 * PI / m).sin() * r0 * r0 * l;
        assert!((v - polygon).abs() < 1e-13 * polygon);
        errors.push((exact - v) / exact);
    }
    for w in errors.windows(2) {
        let r = rate(w[0], w[1]);
        assert!(
            (1.95..2.05).contains(&r),
            "radial rate {r}, errors {errors:?}"
        );
    }
}

#[test]
fn equal_area_section() {
    // Cylinder: exact volume at any resolution.
    let (l, r0) = (0.05, 0.01);
    for n in [1, 2, 3, 5] {
        let c = Fusiform::cylinder(l, r0);
        let m = revolve_with(
            &c,
            Resolution {
                n_axial: 2,
                n_radial: n,
            },
            FibreLayout::Axial,
            Section::EqualArea,
        );
        assert!((m.volume() - c.volume()).abs() < 1e-13 * c.volume());
    }
    // Fusiform: only the axial error remains, second order, below 0.5 % on
    // every level, and the axial rate is clean.
    for res in LEVELS {
        let m = revolve_with(
            &Fusiform::PAPER,
            res,
            FibreLayout::Axial,
            Section::EqualArea,
        );
        let e = (DEFAULT_VOLUME - m.volume()) / DEFAULT_VOLUME;
        assert!(e > 0.0 && e < 5e-3, "{res:?}: {e}");
    }
    let errors: Vec<f64> = [8, 16, 32, 64]
        .iter()
        .map(|&na| {
            let res = Resolution {
                n_axial: na,
                n_radial: 2,
            };
            let v = revolve_with(
                &Fusiform::PAPER,
                res,
                FibreLayout::Axial,
                Section::EqualArea,
            )
            .volume();
            (DEFAULT_VOLUME - v) / DEFAULT_VOLUME
        })
        .collect();
    for w in errors.windows(2) {
        let r = rate(w[0], w[1]);
        assert!((1.95..2.05).contains(&r), "rate {r}, errors {errors:?}");
    }
}

#[test]
fn axial_error_is_second_order() {
    // Fixed cross-section polygon: compare with the exact solid whose
    // section is the 6n-gon scaled by r(x), A_poly/π · V0.
    let n = 3;
    let m6 = 6.0 * n as f64;
    let exact = m6 / 2.0 * (2.0 * PI / m6).sin() / PI * DEFAULT_VOLUME;
    let errors: Vec<f64> = [4, 8, 16, 32, 64]
        .iter()
        .map(|&na| (exact - fusiform(na, n, FibreLayout::Axial).volume()) / exact)
        .collect();
    for w in errors.windows(2).skip(1) {
        let r = rate(w[0], w[1]);
        assert!(
            (1.95..2.05).contains(&r),
            "axial rate {r}, errors {errors:?}"
        );
    }
}

#[test]
fn fibres() {
    let axial = fusiform(8, 2, FibreLayout::Axial);
    assert!(axial.fibre.iter().all(|f| *f == Vector3::x()));

    let p = Fusiform::PAPER;
    let max_slope = p.slope(0.0);
    for res in [LUMPED, LEVELS[2]] {
        let m = revolve(&p, res, FibreLayout::Meridian);
        for (e, f) in m.fibre.iter().enumerate() {
            assert!((f.norm() - 1.0).abs() < 1e-15);
            assert!(f.x > 0.0);
            // Radial part: outward in the first half (r' > 0), inward in
            // the second, never steeper than the outer meridian at the ends.
            let c = m.tets[e].iter().map(|&n| m.nodes[n]).sum::<Vector3<f64>>() / 4.0;
            let radial = f.y * c.y + f.z * c.z;
            if c.x < p.length / 2.0 {
                assert!(radial > 0.0);
            } else {
                assert!(radial < 0.0);
            }
            let tan = (f.y * f.y + f.z * f.z).sqrt() / f.x;
            assert!(tan <= max_slope * (1.0 + 1e-12));
        }
    }
    // On the axis and at the middle (r'(L/2) = 0) the meridian is the axis.
    for x in [0.0, 0.01, 0.025, 0.04, 0.05] {
        assert_eq!(meridian_fibre(&p, x, Vector2::zeros()), Vector3::x());
    }
    for eta in [
        Vector2::new(1.0, 0.0),
        Vector2::new(0.3, -0.8),
        Vector2::new(-0.5, 0.5),
    ] {
        let f = meridian_fibre(&p, p.length / 2.0, eta);
        assert!((f - Vector3::x()).norm() < 1e-15);
        // At the end faces, on the rim: the generatrix direction (1, r'(0)).
        let f0 = meridian_fibre(&p, 0.0, eta / eta.norm());
        let g = Vector3::new(
            1.0,
            max_slope * eta.x / eta.norm(),
            max_slope * eta.y / eta.norm(),
        )
        .normalize();
        assert!((f0 - g).norm() < 1e-15);
    }
    // A cylinder's meridians are axial, exactly.
    let c = revolve(
        &Fusiform::cylinder(0.05, 0.01),
        LUMPED,
        FibreLayout::Meridian,
    );
    assert!(c.fibre.iter().all(|f| *f == Vector3::x()));
}

#[test]
fn general_profile_closure() {
    // A cone frustum r(x) = 1 + x on [0, 2]: exact volume π (r0² + r0 r1 + r1²) L / 3,
    // reproduced by the mesh up to the polygon factor (r is linear).
    let p = FnProfile {
        length: 2.0,
        radius: |x: f64| 1.0 + x,
        slope: |_: f64| 1.0,
    };
    let n = 4;
    let m = revolve(
        &p,
        Resolution {
            n_axial: 5,
            n_radial: n,
        },
        FibreLayout::Meridian,
    );
    let m6 = 6.0 * n as f64;
    let poly = m6 / 2.0 * (2.0 * PI / m6).sin();
    let exact = poly * (1.0 + 3.0 + 9.0) * 2.0 / 3.0;
    assert!((m.volume() - exact).abs() < 1e-12 * exact);
    assert!(m.element_volumes().iter().all(|&v| v > 0.0));
}

/// Prints the table of the module docs (`cargo test --release --lib
/// fe::mesh::tests::level_table -- --ignored --nocapture`).
#[test]
#[ignore]
fn level_table() {
    for (k, res) in LEVELS.iter().enumerate() {
        let m = revolve(&Fusiform::PAPER, *res, FibreLayout::Axial);
        let eq = revolve_with(
            &Fusiform::PAPER,
            *res,
            FibreLayout::Axial,
            Section::EqualArea,
        );
        let (eq_lo, _) = eq.radius_ratio_range();
        let (eqd_lo, eqd_hi) = eq.dihedral_range();
        let (q_lo, q_hi) = m.radius_ratio_range();
        let (d_lo, d_hi) = m.dihedral_range();
        println!(
            "| {k} | {} | {} | {} | {} | {:.3} / {:.3} | {:.1} / {:.1} | {:.2e} | {:.2e} | {:.3} {:.1} / {:.1}",
            res.n_axial,
            res.n_radial,
            m.nodes.len(),
            m.tets.len(),
            q_lo,
            q_hi,
            d_lo.to_degrees(),
            d_hi.to_degrees(),
            (m.volume() - DEFAULT_VOLUME) / DEFAULT_VOLUME,
            (eq.volume() - DEFAULT_VOLUME) / DEFAULT_VOLUME,
            eq_lo,
            eqd_lo.to_degrees(),
            eqd_hi.to_degrees()
        );
    }
}
