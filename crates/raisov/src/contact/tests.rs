//! Tool geometry and the penalty force: signed distances, normals, energy gradient.

use super::*;

#[test]
fn penetration_of_each_shape() {
    let s = ToolShape::Sphere {
        center: [0.0, 0.0, 1.0],
        radius: 0.5,
    };
    let (phi, n) = s.penetration([0.0, 0.0, 0.6], [0.0; 3]).unwrap();
    assert!((phi + 0.1).abs() < 1e-15 && n == [0.0, 0.0, -1.0]);
    assert!(s.penetration([0.0, 0.0, 0.4], [0.0; 3]).is_none());
    // Moved down by 0.2: the point at z = 0.4 is now 0.1 inside.
    let (phi, _) = s.penetration([0.0, 0.0, 0.4], [0.0, 0.0, -0.2]).unwrap();
    assert!((phi + 0.1).abs() < 1e-15);
    let p = ToolShape::Plane {
        point: [0.0, 0.0, 0.0],
        normal: [0.0, 0.0, 1.0],
    };
    assert_eq!(
        p.penetration([3.0, 4.0, -0.25], [0.0; 3]),
        Some((-0.25, [0.0, 0.0, 1.0]))
    );
    assert!(p.penetration([3.0, 4.0, 0.25], [0.0; 3]).is_none());
    let c = ToolShape::Capsule {
        a: [0.0, 0.0, 0.0],
        b: [1.0, 0.0, 0.0],
        radius: 0.1,
    };
    let (phi, n) = c.penetration([0.5, 0.05, 0.0], [0.0; 3]).unwrap();
    assert!((phi + 0.05).abs() < 1e-15 && n == [0.0, 1.0, 0.0]);
    // Beyond an end: the rounded cap.
    let (phi, n) = c.penetration([1.06, 0.0, 0.0], [0.0; 3]).unwrap();
    assert!((phi + 0.04).abs() < 1e-12 && (n[0] - 1.0).abs() < 1e-15);
    assert!(c.penetration([1.2, 0.0, 0.0], [0.0; 3]).is_none());
}

/// The penalty force is minus the gradient of `½ k φ²` (central differences), and the
/// reported net force is the sum of the nodal forces.
#[test]
fn penalty_force_is_the_energy_gradient() {
    let tool = Tool {
        shape: ToolShape::Capsule {
            a: [0.0, 0.0, 0.0],
            b: [0.0, 0.0, 1.0],
            radius: 0.3,
        },
        motion: Motion::Held {
            d: [0.05, 0.0, 0.0],
        },
        stiffness: 1e3,
        friction: None,
    };
    let x0 = vec![0.2, 0.1, 0.5, -0.1, 0.2, 1.1, 1.0, 1.0, 1.0];
    let u = vec![0.01, -0.02, 0.0, 0.0, 0.0, 0.05, 0.0, 0.0, 0.0];
    let mut f = vec![0.0; 9];
    let (e, net, pen) = tool.add_forces(&x0, &u, 0.0, 1.0, &mut f);
    assert!(e > 0.0 && pen > 0.0);
    for k in 0..3 {
        let s: f64 = f.iter().skip(k).step_by(3).sum();
        assert!((s - net[k]).abs() < 1e-12);
    }
    assert_eq!(&f[6..9], &[0.0; 3], "the far node feels nothing");
    let h = 1e-7;
    for i in 0..6 {
        let mut up = u.clone();
        up[i] += h;
        let mut um = u.clone();
        um[i] -= h;
        let ep = tool.add_forces(&x0, &up, 0.0, 1.0, &mut [0.0; 9]).0;
        let em = tool.add_forces(&x0, &um, 0.0, 1.0, &mut [0.0; 9]).0;
        let fd = -(ep - em) / (2.0 * h);
        assert!(
            (fd - f[i]).abs() < 1e-6 * f[i].abs().max(1.0),
            "dof {i}: {fd} vs {}",
            f[i]
        );
    }
}

/// A penalty tool's tangent blocks (`k ∇²(½ φ²)` per penetrating node) plus the elements' are
/// the derivative of the forces, for each shape: a sphere pressed into a tet box, a plane
/// cutting its corner, a capsule across it (side and end cap), moved by its motion at `t`.
#[test]
fn tool_tangent_is_the_force_derivative_for_each_shape() {
    use crate::fem::tests::{assert_tangent_matches_fd, jittered_box, random_u};
    use crate::fem::{FemModel, FemParams};
    use crate::material::{Material, NeoHookean};
    let mesh = jittered_box(3, 0.3);
    let shapes = [
        ToolShape::Sphere {
            center: [0.005, 0.005, 0.0135],
            radius: 0.005,
        },
        ToolShape::Plane {
            point: [0.0, 0.0, 0.0035],
            normal: [0.6, 0.0, 0.8],
        },
        ToolShape::Capsule {
            a: [0.0042, -0.002, 0.0115],
            b: [0.0042, 0.0065, 0.0115],
            radius: 0.0025,
        },
    ];
    for shape in shapes {
        let fem = FemModel::new(
            &mesh,
            FemParams::new(Material::NeoHookean(NeoHookean::from_young(1e4, 0.4))),
        )
        .unwrap();
        let x0 = fem.reference_positions().to_vec();
        let tool = Tool {
            shape: shape.clone(),
            motion: Motion::Ramp {
                d: [0.0, 0.0, -0.001],
                duration: 1.0,
            },
            stiffness: 5e3,
            friction: None,
        };
        let mut c = Contact::new(Box::new(fem), x0, vec![tool]);
        c.set_time(0.5);
        let u = random_u(mesh.num_nodes(), 2e-4, 5);
        let what = format!("{shape:?}");
        let extra = assert_tangent_matches_fd(&mut c, &u, 1e-9, 1e-6, &what);
        assert!(extra > 0.0, "{what}: no node penetrates");
    }
}
