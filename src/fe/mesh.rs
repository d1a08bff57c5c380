//! Procedural 4-node tetrahedral meshes of the paper's fusiform muscle (and of
//! straight cylinders for the homogeneous patch tests). No mesh files.
//!
//! # Geometry
//!
//! The muscle is a solid of revolution about the x axis, from x = 0 (the
//! fixed end face) to x = L (the moved end face), with the radius profile
//!
//! ```text
//! r(x) = r_end + (r_mid − r_end) · sin(π x / L),     0 ≤ x ≤ L,
//! ```
//!
//! C∞ inside, equal to `r_end` at both end faces and to `r_mid` at the middle,
//! where r'(L/2) = 0. The paper's specimen ([`Fusiform::PAPER`], SI units):
//! L = 0.05 m, end diameter 0.009 m, mid diameter 0.0175 m. Its volume
//! (Δ = r_mid − r_end)
//!
//! ```text
//! V0 = ∫₀ᴸ π r(x)² dx = π [ r_end² L + 2 r_end Δ (2L/π) + Δ² L/2 ]
//! ```
//!
//! (∫ sin = 2L/π, ∫ sin² = L/2), i.e. [`DEFAULT_VOLUME`] ≈ 8.4245e-6 m³, and
//! its mean cross-section V0/L0 is [`DEFAULT_MEAN_AREA`] ≈ 1.6849e-4 m².
//!
//! # Mesh
//!
//! - Cross-section: a triangulation of the unit disc ([`unit_disc`]), the
//!   centre point plus `n_radial` rings, ring i (1 ≤ i ≤ n_radial) holding
//!   6·i points equally spaced on the circle of radius i / n_radial (the first
//!   at angle 0), triangles between consecutive rings ("hexagonal" polar grid:
//!   6 (2i − 1) triangles in annulus i, 6 n_radial² in all). No angular sector
//!   collapses on the axis: the six triangles around the centre are equilateral.
//! - The same disc on each of the `n_axial + 1` slices x_s = s L / n_axial,
//!   scaled by r(x_s): node (x_s, r(x_s) η) for disc point η. Node numbering is
//!   slice-major: node = s · nodes_per_slice + disc index.
//! - Each disc triangle, extruded between consecutive slices, is a (tapered)
//!   prism split into 3 tetrahedra. With the triangle's disc indices sorted,
//!   v0 < v1 < v2, bottom a_k and top b_k:
//!   (a0, a1, a2, b2), (a0, b1, a1, b2), (a0, b0, b1, b2). On the quad between
//!   disc points u < v that cuts along the diagonal a_u – b_v, whichever prism
//!   it belongs to, so neighbouring prisms split their shared face the same
//!   way and the mesh is conforming. Every tetrahedron has positive signed
//!   volume (orientation fixed from the disc triangle's orientation; the three
//!   volumes are h r_a² A/3, h r_a r_b A/3, h r_b² A/3 for a disc triangle of
//!   area A, slice spacing h and slice radii r_a, r_b).
//! - Counts: nodes (n_axial + 1)(1 + 3 n_radial (n_radial + 1)), tetrahedra
//!   18 n_radial² n_axial, boundary triangles 12 n_radial² (the two end discs)
//!   + 12 n_radial n_axial (the lateral surface).
//! - Fibres, one unit vector per tetrahedron ([`FibreLayout`]): along the axis,
//!   or along the profile's meridians (x, r(x) η) for fixed η, whose tangent is
//!   (1, r'(x) η) / ‖·‖ — i.e. (1, r' cos θ, r' sin θ)/‖·‖ scaled by the relative
//!   radius |η| — evaluated at the element centroid (x_c, η_c).
//!
//! The volume converges to V0 at second order in the resolution: the disc is
//! the inscribed polygon with 6 n_radial sides (area deficit O(n_radial⁻²)),
//! and r is interpolated linearly between slices (O(n_axial⁻²)).
//!
//! # Levels
//!
//! [`LEVELS`] keeps n_axial = 6 n_radial, so that every level has the same
//! element shapes. At 4:1 the prisms near the thin end faces are about 3× as
//! long as wide; around 6:1–8:1 is best for this profile (the radius ratios,
//! dihedral angles and volume errors of each level are in docs/fe.md; the
//! tests bound them).
//!
//! Any other resolution can be built.
//!
//! [`LUMPED`] (16 × 3, 2,592 tetrahedra, slices graded 0.9 toward the end
//! faces by [`graded_slice`], rings graded 0.6 toward the lateral surface by
//! [`graded_ring`]: [`LUMPED_GRADING`]) is the FE muscle's small default; the
//! convergence study that chose it is in docs/fe.md. Its end layers are a
//! tenth of the uniform spacing thick, so its elements there are flat — the
//! quality table above is for uniform slices and rings.

use nalgebra::{Vector2, Vector3};
use std::collections::HashMap;
use std::f64::consts::PI;

// The specimen's dimensions and closed-form volume live in `crate::specimen`
// (shared with the 1D FMU, whose default area is the mean cross-section).
pub use crate::specimen::{
    fusiform_volume, END_RADIUS as DEFAULT_END_RADIUS, LENGTH as DEFAULT_LENGTH,
    MEAN_AREA as DEFAULT_MEAN_AREA, MID_RADIUS as DEFAULT_MID_RADIUS, VOLUME as DEFAULT_VOLUME,
};

/// A radius profile of a solid of revolution about the x axis, 0 ≤ x ≤ length.
pub trait Profile {
    /// Axial length L.
    fn length(&self) -> f64;
    /// Radius r(x) (must be positive on [0, L]).
    fn radius(&self, x: f64) -> f64;
    /// Slope r'(x) (used only by the meridian fibre layout).
    fn slope(&self, x: f64) -> f64;
}

/// The fusiform profile r(x) = r_end + (r_mid − r_end) sin(π x / L); a
/// straight cylinder when `r_end == r_mid`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fusiform {
    /// Length L.
    pub length: f64,
    /// Radius of both end faces.
    pub r_end: f64,
    /// Radius at the middle x = L/2.
    pub r_mid: f64,
}

impl Fusiform {
    /// The paper's specimen: L = 5 cm, diameters 0.9 cm (ends), 1.75 cm (middle).
    pub const PAPER: Fusiform = Fusiform {
        length: DEFAULT_LENGTH,
        r_end: DEFAULT_END_RADIUS,
        r_mid: DEFAULT_MID_RADIUS,
    };

    /// A straight circular cylinder.
    pub fn cylinder(length: f64, radius: f64) -> Self {
        Fusiform {
            length,
            r_end: radius,
            r_mid: radius,
        }
    }

    /// Volume, [`fusiform_volume`].
    pub fn volume(&self) -> f64 {
        fusiform_volume(self.length, self.r_end, self.r_mid)
    }

    /// Mean cross-section V0 / L.
    pub fn mean_area(&self) -> f64 {
        self.volume() / self.length
    }
}

impl Default for Fusiform {
    fn default() -> Self {
        Fusiform::PAPER
    }
}

impl Profile for Fusiform {
    fn length(&self) -> f64 {
        self.length
    }
    fn radius(&self, x: f64) -> f64 {
        self.r_end + (self.r_mid - self.r_end) * (PI * x / self.length).sin()
    }
    fn slope(&self, x: f64) -> f64 {
        (self.r_mid - self.r_end) * PI / self.length * (PI * x / self.length).cos()
    }
}

/// A general profile from closures: `radius(x)` and its derivative `slope(x)`.
#[derive(Clone, Copy, Debug)]
pub struct FnProfile<R, S> {
    /// Length L.
    pub length: f64,
    /// r(x).
    pub radius: R,
    /// r'(x).
    pub slope: S,
}

impl<R: Fn(f64) -> f64, S: Fn(f64) -> f64> Profile for FnProfile<R, S> {
    fn length(&self) -> f64 {
        self.length
    }
    fn radius(&self, x: f64) -> f64 {
        (self.radius)(x)
    }
    fn slope(&self, x: f64) -> f64 {
        (self.slope)(x)
    }
}

/// Fibre direction per element.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FibreLayout {
    /// Along the long axis, exactly (1, 0, 0).
    #[default]
    Axial,
    /// Along the meridians (x, r(x) η): (1, r'(x_c) η_c) / ‖·‖ at the element
    /// centroid, see [`meridian_fibre`]. Axial on the axis and where r' = 0.
    Meridian,
}

/// Tangent of the meridian through the point (x, r(x) η) (η in the unit disc,
/// (y, z) components): (1, r'(x) η_y, r'(x) η_z) / ‖·‖, i.e. the profile's
/// generatrix direction (1, r' cos θ, r' sin θ) scaled by the relative radius
/// |η|. Exactly (1, 0, 0) for η = 0 or r'(x) = 0.
pub fn meridian_fibre<P: Profile + ?Sized>(profile: &P, x: f64, eta: Vector2<f64>) -> Vector3<f64> {
    let s = profile.slope(x);
    Vector3::new(1.0, s * eta.x, s * eta.y).normalize()
}

/// How the cross-section polygon (6 n_radial sides) approximates the circle
/// of radius r(x).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Section {
    /// Outer nodes on the circle (on the true surface): the inscribed polygon,
    /// cross-section area short by 1 − (3n/π) sin(π/3n) (4.5 % for
    /// n_radial = 2, 1.1 % for 4, 0.3 % for 8).
    #[default]
    Inscribed,
    /// The whole disc scaled by √(π / A_polygon) so that each slice's
    /// polygon has the circle's area π r(x)²; only the axial (linear
    /// interpolation of r) volume error remains. Outer nodes lie slightly
    /// outside the surface (by 2.3 % of r for n_radial = 2).
    EqualArea,
}

impl Section {
    /// Factor applied to the unit disc's coordinates.
    pub fn scale(self, n_radial: usize) -> f64 {
        match self {
            Section::Inscribed => 1.0,
            Section::EqualArea => (PI / unit_polygon_area(n_radial)).sqrt(),
        }
    }
}

/// Area of the regular 6 n_radial-gon inscribed in the unit circle, the area
/// of [`unit_disc`]: (m/2) sin(2π/m), m = 6 n_radial.
pub fn unit_polygon_area(n_radial: usize) -> f64 {
    let m = 6.0 * n_radial as f64;
    m / 2.0 * (2.0 * PI / m).sin()
}

/// Mesh resolution: slices along the axis and rings in the cross-section.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Resolution {
    /// Number of element layers along x (≥ 1).
    pub n_axial: usize,
    /// Number of rings in the cross-section (≥ 1).
    pub n_radial: usize,
}

impl Resolution {
    /// Points of one cross-section: 1 + 3 n_radial (n_radial + 1).
    pub const fn nodes_per_slice(&self) -> usize {
        1 + 3 * self.n_radial * (self.n_radial + 1)
    }
    /// Nodes: (n_axial + 1) · nodes per slice.
    pub const fn nodes(&self) -> usize {
        (self.n_axial + 1) * self.nodes_per_slice()
    }
    /// Triangles of one cross-section: 6 n_radial².
    pub const fn triangles_per_slice(&self) -> usize {
        6 * self.n_radial * self.n_radial
    }
    /// Tetrahedra: 3 · 6 n_radial² · n_axial.
    pub const fn tets(&self) -> usize {
        3 * self.triangles_per_slice() * self.n_axial
    }
    /// Boundary triangles: 2 · 6 n_radial² (end discs) + 12 n_radial n_axial (lateral).
    pub const fn boundary_faces(&self) -> usize {
        2 * self.triangles_per_slice() + 12 * self.n_radial * self.n_axial
    }
}

/// The small default ("lumped") mesh of the FE muscle: 16 × 3, 2,592
/// tetrahedra, graded by [`LUMPED_GRADING`] toward the clamped faces' rims
/// (the convergence study of docs/fe.md chose both).
pub const LUMPED: Resolution = Resolution {
    n_axial: 16,
    n_radial: 3,
};
/// The grading of the lumped mesh ([`graded_slice`], [`graded_ring`]).
pub const LUMPED_GRADING: Grading = Grading {
    axial: 0.9,
    radial: 0.6,
};

/// How a mesh's element layers are graded: the slices toward the end faces
/// ([`graded_slice`], `axial`) and the rings of the cross-section toward the
/// lateral surface ([`graded_ring`], `radial`), each in [0, 0.95]; together
/// they put the small elements at the end faces' rims, where the clamped
/// specimen's pressure is singular (docs/fe.md, verification item 3).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grading {
    /// Axial grading β: the end layers are (1 − β) times the uniform spacing.
    pub axial: f64,
    /// Radial grading g: the outer ring is about (1 − g) times the uniform width.
    pub radial: f64,
}

impl Grading {
    /// Uniform slices and rings.
    pub const UNIFORM: Grading = Grading {
        axial: 0.0,
        radial: 0.0,
    };

    /// Slices graded by `axial`, uniform rings.
    pub const fn axial(axial: f64) -> Grading {
        Grading { axial, radial: 0.0 }
    }

    /// Both gradings in [0, [`MAX_GRADING`]], or a message naming the one that is not.
    pub fn check(&self) -> Result<(), String> {
        for (name, g) in [("axial", self.axial), ("radial", self.radial)] {
            if !(0.0..=MAX_GRADING).contains(&g) {
                return Err(format!("{name} grading {g} outside [0, {MAX_GRADING}]"));
            }
        }
        Ok(())
    }
}

/// Refinement levels, n_axial = 6 n_radial (864, 2,916, 6,912, 23,328, 55,296
/// tetrahedra); levels 0, 2, 4 halve the element size twice. See the module
/// documentation for why 6:1.
pub const LEVELS: [Resolution; 5] = [
    Resolution {
        n_axial: 12,
        n_radial: 2,
    },
    Resolution {
        n_axial: 18,
        n_radial: 3,
    },
    Resolution {
        n_axial: 24,
        n_radial: 4,
    },
    Resolution {
        n_axial: 36,
        n_radial: 6,
    },
    Resolution {
        n_axial: 48,
        n_radial: 8,
    },
];

/// The cross-section: the unit disc as the centre plus `n_radial` rings, ring
/// i with 6 i points at radius i / n_radial, and its triangles, counter-clockwise
/// in the (y, z) plane. Point (i, k) (ring i, k-th point, angle 2πk / 6i) has
/// index 1 + 3 i (i − 1) + k; the centre is 0.
pub fn unit_disc(n_radial: usize) -> (Vec<Vector2<f64>>, Vec<[usize; 3]>) {
    unit_disc_graded(n_radial, 0.0)
}

/// [`unit_disc`] with ring i at radius [`graded_ring`]`(i, n_radial, grading)`
/// instead of i / n_radial (the same points on each ring, the same triangles).
pub fn unit_disc_graded(n_radial: usize, grading: f64) -> (Vec<Vector2<f64>>, Vec<[usize; 3]>) {
    assert!(n_radial >= 1, "n_radial must be at least 1");
    let ring_start = |i: usize| if i == 0 { 0 } else { 1 + 3 * i * (i - 1) };
    let ring_len = |i: usize| if i == 0 { 1 } else { 6 * i };
    let point = |i: usize, k: usize| ring_start(i) + k % ring_len(i);

    let mut points = Vec::with_capacity(1 + 3 * n_radial * (n_radial + 1));
    points.push(Vector2::zeros());
    for i in 1..=n_radial {
        let rho = graded_ring(i, n_radial, grading);
        for k in 0..6 * i {
            let theta = 2.0 * PI * k as f64 / (6 * i) as f64;
            points.push(Vector2::new(rho * theta.cos(), rho * theta.sin()));
        }
    }

    let mut triangles = Vec::with_capacity(6 * n_radial * n_radial);
    for i in 1..=n_radial {
        for s in 0..6 {
            // Outer ring i: points s·i ..= s·i + i of the sector; inner ring
            // i − 1: points s(i−1) ..= s(i−1) + i − 1 (the centre for i = 1).
            for j in 0..i {
                let inner = point(i - 1, s * (i - 1) + j);
                triangles.push([point(i, s * i + j), point(i, s * i + j + 1), inner]);
            }
            for j in 0..i - 1 {
                triangles.push([
                    point(i - 1, s * (i - 1) + j),
                    point(i, s * i + j + 1),
                    point(i - 1, s * (i - 1) + j + 1),
                ]);
            }
        }
    }
    (points, triangles)
}

/// A tetrahedral mesh of a solid of revolution about the x axis.
#[derive(Clone, Debug)]
pub struct Mesh {
    /// Node coordinates (x along the muscle).
    pub nodes: Vec<Vector3<f64>>,
    /// Tetrahedra, positively oriented (see [`tet_signed_volume`]).
    pub tets: Vec<[usize; 4]>,
    /// Nodes of the end face x = 0 (slice 0), in disc order.
    pub fixed_face: Vec<usize>,
    /// Nodes of the end face x = L (last slice), in disc order.
    pub moved_face: Vec<usize>,
    /// Unit fibre direction per tetrahedron.
    pub fibre: Vec<Vector3<f64>>,
    /// Length L.
    pub length: f64,
    /// Resolution it was built with.
    pub resolution: Resolution,
    /// How the cross-section polygon approximates the circle.
    pub section: Section,
    /// Grading of the slices and rings ([`Grading`]).
    pub grading: Grading,
    /// Unit-disc coordinates η of each node (node = (x, r(x) η)).
    pub disc: Vec<Vector2<f64>>,
}

/// The paper's fusiform specimen ([`Fusiform::PAPER`]) at the given resolution.
pub fn fusiform(n_axial: usize, n_radial: usize, fibres: FibreLayout) -> Mesh {
    revolve(&Fusiform::PAPER, Resolution { n_axial, n_radial }, fibres)
}

/// A straight circular cylinder (axial fibres), for homogeneous patch tests.
pub fn cylinder(length: f64, radius: f64, n_axial: usize, n_radial: usize) -> Mesh {
    revolve(
        &Fusiform::cylinder(length, radius),
        Resolution { n_axial, n_radial },
        FibreLayout::Axial,
    )
}

/// Mesh the solid of revolution of `profile` with [`Section::Inscribed`]
/// cross-sections, see [`revolve_with`].
pub fn revolve<P: Profile + ?Sized>(
    profile: &P,
    resolution: Resolution,
    fibres: FibreLayout,
) -> Mesh {
    revolve_with(profile, resolution, fibres, Section::Inscribed)
}

/// Largest grading [`graded_slice`] and [`graded_ring`] accept (end layers
/// 1/20 of the uniform spacing).
pub const MAX_GRADING: f64 = 0.95;

/// Position of slice s of n on [0, L] with axial grading β ∈ [0, 1):
/// x = L (u − β sin(2πu)/(2π)), u = s/n. The spacing dx/du = L (1 − β cos 2πu)
/// is smooth, symmetric and positive: the layers at both end faces are
/// (1 − β) times, those in the middle (1 + β) times the uniform spacing.
/// Why: with the end faces clamped, the nearly incompressible specimen has a
/// boundary layer at each of them where the error of the linear tetrahedra
/// sits (docs/fe.md, the convergence study: on uniform slices refining axially
/// cuts the error, radially barely), so grading puts the layers where they pay.
pub fn graded_slice(s: usize, n: usize, length: f64, grading: f64) -> f64 {
    if s == n {
        return length;
    }
    let u = s as f64 / n as f64;
    let two_pi = 2.0 * std::f64::consts::PI;
    length * (u - grading * (two_pi * u).sin() / two_pi)
}

/// Radius of ring i of n of the unit disc with radial grading g ∈ [0, 1):
/// ρ = u + g u (1 − u), u = i/n. The spacing dρ/du = 1 + g (1 − 2u) is
/// positive: 1 − g at the lateral surface, 1 + g at the axis. Why: once the
/// slices are graded toward the end faces, what is left of the force's
/// discretization error sits at the faces' rims, where the clamped face meets
/// the free surface (docs/fe.md, the convergence study and item 3), so the
/// rings are graded toward the surface too.
pub fn graded_ring(i: usize, n: usize, grading: f64) -> f64 {
    if i == n {
        return 1.0;
    }
    let u = i as f64 / n as f64;
    u + grading * u * (1.0 - u)
}

/// [`revolve_graded`] with uniform slices.
pub fn revolve_with<P: Profile + ?Sized>(
    profile: &P,
    resolution: Resolution,
    fibres: FibreLayout,
    section: Section,
) -> Mesh {
    revolve_graded(profile, resolution, fibres, section, Grading::UNIFORM)
}

/// Mesh the solid of revolution of `profile`: the unit disc with its rings
/// graded by `grading.radial` ([`unit_disc_graded`]) scaled by
/// `section.scale(n_radial)` · r(x_s) on each slice x_s ([`graded_slice`]
/// with grading `grading.axial`), each prism split into three positively
/// oriented tetrahedra by the sorted-index rule (see the module
/// documentation).
///
/// # Panics
/// If a resolution is zero, the length is not positive and finite, r is not
/// positive and finite on a slice, or a grading is outside
/// [0, [`MAX_GRADING`]].
pub fn revolve_graded<P: Profile + ?Sized>(
    profile: &P,
    resolution: Resolution,
    fibres: FibreLayout,
    section: Section,
    grading: Grading,
) -> Mesh {
    if let Err(e) = grading.check() {
        panic!("{e}");
    }
    let Resolution { n_axial, n_radial } = resolution;
    assert!(n_axial >= 1, "n_axial must be at least 1");
    let length = profile.length();
    assert!(
        length.is_finite() && length > 0.0,
        "length must be positive, got {length}"
    );
    let (disc_points, triangles) = unit_disc_graded(n_radial, grading.radial);
    let nps = disc_points.len();
    let k = section.scale(n_radial);

    let slice_x = |s: usize| graded_slice(s, n_axial, length, grading.axial);
    let mut nodes = Vec::with_capacity((n_axial + 1) * nps);
    let mut disc = Vec::with_capacity((n_axial + 1) * nps);
    for s in 0..=n_axial {
        let x = slice_x(s);
        let r = profile.radius(x);
        assert!(
            r.is_finite() && r > 0.0,
            "radius must be positive, got r({x}) = {r}"
        );
        let r = k * r;
        for eta in &disc_points {
            nodes.push(Vector3::new(x, r * eta.x, r * eta.y));
            disc.push(*eta);
        }
    }

    // Sort each triangle's disc indices once; remember whether sorting flipped it.
    let sorted: Vec<([usize; 3], bool)> = triangles
        .iter()
        .map(|t| {
            let mut v = *t;
            v.sort_unstable();
            let (p0, p1, p2) = (disc_points[v[0]], disc_points[v[1]], disc_points[v[2]]);
            let orient = (p1 - p0).perp(&(p2 - p0));
            (v, orient > 0.0)
        })
        .collect();

    let mut tets = Vec::with_capacity(resolution.tets());
    for s in 0..n_axial {
        for &(v, ccw) in &sorted {
            let a = v.map(|k| s * nps + k);
            let b = v.map(|k| (s + 1) * nps + k);
            for mut t in [
                [a[0], a[1], a[2], b[2]],
                [a[0], b[1], a[1], b[2]],
                [a[0], b[0], b[1], b[2]],
            ] {
                if !ccw {
                    t.swap(0, 1);
                }
                tets.push(t);
            }
        }
    }

    let fibre = tets
        .iter()
        .map(|t| match fibres {
            FibreLayout::Axial => Vector3::x(),
            FibreLayout::Meridian => {
                let xc = t.iter().map(|&n| nodes[n].x).sum::<f64>() / 4.0;
                let eta = t.iter().map(|&n| disc[n]).sum::<Vector2<f64>>() / 4.0;
                meridian_fibre(profile, xc, eta)
            }
        })
        .collect();

    Mesh {
        fixed_face: (0..nps).collect(),
        moved_face: (n_axial * nps..(n_axial + 1) * nps).collect(),
        nodes,
        tets,
        fibre,
        length,
        resolution,
        section,
        grading,
        disc,
    }
}

/// Signed volume of the tetrahedron (p0, p1, p2, p3):
/// (p1 − p0) · ((p2 − p0) × (p3 − p0)) / 6, positive when p3 lies on the side
/// of (p0, p1, p2) that the counter-clockwise normal points to.
pub fn tet_signed_volume(p: &[Vector3<f64>; 4]) -> f64 {
    (p[1] - p[0]).dot(&(p[2] - p[0]).cross(&(p[3] - p[0]))) / 6.0
}

/// Radius ratio 3 r_in / R_circ of a tetrahedron: 1 for the regular one, 0
/// for a degenerate one.
pub fn tet_radius_ratio(p: &[Vector3<f64>; 4]) -> f64 {
    let (a, b, c) = (p[1] - p[0], p[2] - p[0], p[3] - p[0]);
    let six_v = a.dot(&b.cross(&c)).abs();
    // Circumradius: |a|²(b×c) + |b|²(c×a) + |c|²(a×b) over 2 |a·(b×c)|.
    let circ = (a.norm_squared() * b.cross(&c)
        + b.norm_squared() * c.cross(&a)
        + c.norm_squared() * a.cross(&b))
    .norm()
        / (2.0 * six_v);
    // Inradius: 3V / total face area.
    let faces = [(0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)];
    let area: f64 = faces
        .iter()
        .map(|&(i, j, k)| (p[j] - p[i]).cross(&(p[k] - p[i])).norm() / 2.0)
        .sum();
    let inr = six_v / 2.0 / area;
    3.0 * inr / circ
}

/// The six interior dihedral angles of a tetrahedron \[rad\], one per edge.
pub fn tet_dihedral_angles(p: &[Vector3<f64>; 4]) -> [f64; 6] {
    const EDGES: [(usize, usize, usize, usize); 6] = [
        (0, 1, 2, 3),
        (0, 2, 1, 3),
        (0, 3, 1, 2),
        (1, 2, 0, 3),
        (1, 3, 0, 2),
        (2, 3, 0, 1),
    ];
    EDGES.map(|(i, j, k, l)| {
        let e = p[j] - p[i];
        let n1 = e.cross(&(p[k] - p[i]));
        let n2 = e.cross(&(p[l] - p[i]));
        n1.cross(&n2).norm().atan2(n1.dot(&n2))
    })
}

impl Mesh {
    /// Node coordinates of tetrahedron `e`.
    pub fn tet_points(&self, e: usize) -> [Vector3<f64>; 4] {
        self.tets[e].map(|n| self.nodes[n])
    }

    /// Signed volume of every tetrahedron (all positive).
    pub fn element_volumes(&self) -> Vec<f64> {
        (0..self.tets.len())
            .map(|e| tet_signed_volume(&self.tet_points(e)))
            .collect()
    }

    /// Total volume.
    pub fn volume(&self) -> f64 {
        self.element_volumes().iter().sum()
    }

    /// Per tetrahedron, whether it has a node on the rim of an end face: the
    /// outer ring of the face's disc, where the clamped face meets the free
    /// surface (the corner at which the nearly incompressible pressure
    /// concentrates; docs/fe.md, verification item 3).
    pub fn at_an_end_rim(&self) -> Vec<bool> {
        let r_max = self.disc.iter().map(|eta| eta.norm()).fold(0.0, f64::max);
        let mut rim = vec![false; self.nodes.len()];
        for &a in self.fixed_face.iter().chain(&self.moved_face) {
            rim[a] = self.disc[a].norm() >= 0.999 * r_max;
        }
        self.tets
            .iter()
            .map(|t| t.iter().any(|&a| rim[a]))
            .collect()
    }

    /// Per tetrahedron, the distance of its centroid from the nearer end-face
    /// rim (the circle through the face's outermost nodes), in the reference
    /// configuration: where a bound on a field that is singular at the rims
    /// can hold under refinement, it holds beyond a fixed distance from them.
    pub fn end_rim_distances(&self) -> Vec<f64> {
        let circle = |face: &[usize]| {
            let x = face.iter().map(|&a| self.nodes[a].x).sum::<f64>() / face.len() as f64;
            let r = face
                .iter()
                .map(|&a| self.nodes[a].yz().norm())
                .fold(0.0, f64::max);
            (x, r)
        };
        let rims = [circle(&self.fixed_face), circle(&self.moved_face)];
        (0..self.tets.len())
            .map(|e| {
                let c = self.tet_points(e).iter().sum::<Vector3<f64>>() / 4.0;
                let rho = c.yz().norm();
                rims.iter()
                    .map(|&(x, r)| (c.x - x).hypot(rho - r))
                    .fold(f64::INFINITY, f64::min)
            })
            .collect()
    }

    /// Smallest and largest radius ratio ([`tet_radius_ratio`]) over the elements.
    pub fn radius_ratio_range(&self) -> (f64, f64) {
        (0..self.tets.len())
            .map(|e| tet_radius_ratio(&self.tet_points(e)))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), q| {
                (lo.min(q), hi.max(q))
            })
    }

    /// Smallest and largest dihedral angle \[rad\] over the elements.
    pub fn dihedral_range(&self) -> (f64, f64) {
        (0..self.tets.len())
            .flat_map(|e| tet_dihedral_angles(&self.tet_points(e)))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), q| {
                (lo.min(q), hi.max(q))
            })
    }

    /// Triangles belonging to exactly one tetrahedron, each oriented with its
    /// normal pointing out of that tetrahedron. Panics if a triangle is shared
    /// by more than two tetrahedra (a non-manifold mesh).
    pub fn boundary_faces(&self) -> Vec<[usize; 3]> {
        let mut seen: HashMap<[usize; 3], (usize, [usize; 3])> =
            HashMap::with_capacity(2 * self.tets.len());
        for t in &self.tets {
            // Faces opposite vertex 0..3, outward for a positive tetrahedron.
            for f in [
                [t[1], t[2], t[3]],
                [t[0], t[3], t[2]],
                [t[0], t[1], t[3]],
                [t[0], t[2], t[1]],
            ] {
                let mut key = f;
                key.sort_unstable();
                let entry = seen.entry(key).or_insert((0, f));
                entry.0 += 1;
                assert!(
                    entry.0 <= 2,
                    "face {key:?} is shared by more than two tetrahedra"
                );
            }
        }
        let mut faces: Vec<[usize; 3]> = seen
            .into_values()
            .filter(|&(n, _)| n == 1)
            .map(|(_, f)| f)
            .collect();
        faces.sort_unstable();
        faces
    }
}

#[cfg(test)]
mod tests;
