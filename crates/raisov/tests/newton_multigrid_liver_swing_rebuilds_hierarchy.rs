//! Regression: Newton-multigrid on the liver L1 (coarse level L2), held on the cap of its top
//! and sagging under gravity from rest. The first Newton step, the linear response, swings the
//! soft liver through its equilibrium and up the far side of Π along the step; Armijo's rule
//! accepted it, the tangent there was indefinite, and the regularisation's rise and fall
//! rebuilt the multigrid hierarchy 12 times in 13 Newton iterations. The line search's
//! curvature condition (`statics::newton`, module docs) now steps back to the secant
//! estimate of the minimum along the step. Checked: convergence with at most 2 hierarchies and
//! 11 Newton iterations (2 and 9 measured: the hierarchy built at rest, where the step is
//! damped, and its provisional rebuild after the first full step), to the equilibrium of direct Newton within 1e-8 of
//! the largest displacement.
//!
//! Slow (liver meshes): `#[ignore]`d in the fast loop, run in CI by
//! `cargo test --workspace -- --ignored`.

use raisov::hierarchy::Transfer;
use raisov::statics::newton::MultigridPcg;

mod common;

#[test]
#[ignore = "slow: liver meshes; run in release with --ignored"]
fn newton_multigrid_liver_swing_keeps_one_hierarchy() {
    let sc = common::liver_l1_sag("", "liver-swing.toml");
    let meshes = sc.level_meshes().unwrap();
    let down = vec![Transfer::build(&meshes[0].nodes, &meshes[1]).unwrap()];
    let (u, out) = common::newton_from_rest(&sc, &down, Some(MultigridPcg::default()));
    assert!(
        out.multigrid_setups <= 2 && out.newton_steps <= 11,
        "{} hierarchies, {} Newton iterations",
        out.multigrid_setups,
        out.newton_steps
    );
    let (reference, _) = common::newton_from_rest(&sc, &down, None);
    let (err, scale) = common::max_diff(&u, &reference);
    assert!(err <= 1e-8 * scale, "{err:.3e} of {scale:.3e}");
}
