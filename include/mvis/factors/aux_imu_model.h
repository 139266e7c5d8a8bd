// How an auxiliary IMU's velocity enters the estimator (see aux_imu_factor.h).
#pragma once

namespace mvis {

enum class AuxImuModel {
  kVelocityState,  // a velocity state per window time (report Sec. 3.1; consistent)
  kRigidVelocity,  // the rigid-body velocity from the base state (report Appendix B; inconsistent
                   // on degenerate motion, Sec. 6.3)
};

}  // namespace mvis
