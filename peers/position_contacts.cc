// Obstacle contacts on positions (Macklin et al. 2014, Eq. 24–25; docs/model.md §10).
#include "peers/position_contacts.h"

namespace clothbench {

int ProjectOntoObstacles(const ParticleSystem& sys, const Eigen::VectorXd& w, double t_end, double dt,
                         const MatrixN3& x, MatrixN3* p) {
  int colliding = 0;
  const int n = sys.num_particles();
  for (const Obstacle& o : sys.obstacles()) {
    const ObstaclePose pose = o.PoseAt(t_end);
    const double delta = o.spec().collision_distance, mu = o.spec().friction;
    for (int i = 0; i < n; ++i) {
      if (w(i) == 0.0) continue;
      Vector3 q = p->row(i).transpose(), dir;
      const double d = o.SignedDistance(pose, q, &dir);
      if (!(d < delta)) continue;
      ++colliding;
      const double depth = delta - d;
      q += depth * dir;
      if (mu > 0.0) {
        Vector3 rel = q - x.row(i).transpose();
        if (!pose.identity) rel -= pose.Velocity(q) * dt;
        const Vector3 tangential = rel - rel.dot(dir) * dir;
        const double len = tangential.norm();
        if (len < mu * depth)
          q -= tangential;
        else
          q -= tangential * (mu * depth / len);
      }
      p->row(i) = q.transpose();
    }
  }
  return colliding;
}

}  // namespace clothbench
