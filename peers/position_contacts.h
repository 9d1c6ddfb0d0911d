// Obstacle contacts on positions, for the peers that move particles by
// position (XPBD, projective dynamics): the inequality C = d(p) − δ ≥ 0 on
// the signed distance d with zero compliance, and Coulomb friction on the
// tangential displacement (Macklin, Müller, Chentanez, Kim 2014, "Unified
// particle physics for real-time applications", Eq. 24–25) with
// μ_s = μ_k = c_f (docs/model.md §10).
#ifndef CLOTHBENCH_PEERS_POSITION_CONTACTS_H_
#define CLOTHBENCH_PEERS_POSITION_CONTACTS_H_

#include "model/particle_system.h"

namespace clothbench {

/// Moves every particle of `p` inside an obstacle's collision area to its
/// border along the distance's direction D, then removes its tangential
/// displacement relative to the obstacle since `x`: all of it while it is
/// below μ (δ − d) (static), otherwise by μ (δ − d) (kinetic).
/// @param sys the model (its obstacles, at their pose at `t_end`)
/// @param w inverse masses [1/kg]; particles with w = 0 (fixed) are not moved
/// @param t_end time of the positions `p` [s]
/// @param dt time since `x` [s] (the obstacle's own motion over it is not friction)
/// @param x N×3 positions at the start of the (sub)step [m]
/// @param p N×3 positions at its end [m], updated
/// @return the particles found in an obstacle's collision area
int ProjectOntoObstacles(const ParticleSystem& sys, const Eigen::VectorXd& w, double t_end, double dt,
                         const MatrixN3& x, MatrixN3* p);

}  // namespace clothbench

#endif  // CLOTHBENCH_PEERS_POSITION_CONTACTS_H_
