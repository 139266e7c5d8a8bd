// Camera models against OpenCV's own implementations (an independent reference), round trips,
// and autodiff-friendliness.
#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <opencv2/calib3d.hpp>
#include <random>

#include "mvis/camera/camera_model.h"

namespace mvis {
namespace {

Camera radtanCamera() {
  Camera cam;
  cam.intrinsics << 458.654, 457.296, 367.215, 248.375;
  cam.distortion_model = DistortionModel::kRadtan;
  cam.distortion_coeffs << -0.28340811, 0.07395907, 0.00019359, 1.76187114e-05;
  cam.resolution = {752, 480};
  return cam;
}

Camera equidistantCamera() {
  Camera cam;
  cam.intrinsics << 285.7, 285.9, 420.3, 402.1;
  cam.distortion_model = DistortionModel::kEquidistant;
  cam.distortion_coeffs << -0.0072, 0.0412, -0.0386, 0.0065;
  cam.resolution = {848, 800};
  return cam;
}

std::vector<Eigen::Vector3d> pointsInView(std::mt19937& rng, double max_tan, int count) {
  std::uniform_real_distribution<double> u(-max_tan, max_tan);
  std::uniform_real_distribution<double> depth(0.3, 5.0);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < count; ++i) {
    const double z = depth(rng);
    points.emplace_back(u(rng) * z, u(rng) * z, z);
  }
  return points;
}

// OpenCV computes in double with the same formulas; agreement to 1e-9 px is round-off.
constexpr double kReferenceTol = 1e-9;

TEST(CameraModel, RadtanMatchesOpenCv) {
  const Camera cam = radtanCamera();
  std::mt19937 rng(3);
  const auto points = pointsInView(rng, 0.7, 200);
  std::vector<cv::Point3d> object;
  for (const auto& p : points) object.emplace_back(p.x(), p.y(), p.z());
  const cv::Matx33d K(cam.intrinsics[0], 0, cam.intrinsics[2], 0, cam.intrinsics[1],
                      cam.intrinsics[3], 0, 0, 1);
  const std::vector<double> dist = {cam.distortion_coeffs[0], cam.distortion_coeffs[1],
                                    cam.distortion_coeffs[2], cam.distortion_coeffs[3]};
  std::vector<cv::Point2d> expected;
  cv::projectPoints(object, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), K, dist, expected);
  for (std::size_t i = 0; i < points.size(); ++i) {
    Eigen::Vector2d uv;
    ASSERT_TRUE(projectToPixel(cam, points[i], &uv));
    EXPECT_NEAR(uv.x(), expected[i].x, kReferenceTol);
    EXPECT_NEAR(uv.y(), expected[i].y, kReferenceTol);
  }
}

TEST(CameraModel, EquidistantMatchesOpenCvFisheye) {
  const Camera cam = equidistantCamera();
  std::mt19937 rng(4);
  const auto points = pointsInView(rng, 1.5, 200);  // up to ~65 degrees off axis
  std::vector<cv::Point3d> object;
  for (const auto& p : points) object.emplace_back(p.x(), p.y(), p.z());
  const cv::Matx33d K(cam.intrinsics[0], 0, cam.intrinsics[2], 0, cam.intrinsics[1],
                      cam.intrinsics[3], 0, 0, 1);
  const cv::Vec4d dist(cam.distortion_coeffs[0], cam.distortion_coeffs[1], cam.distortion_coeffs[2],
                       cam.distortion_coeffs[3]);
  std::vector<cv::Point2d> expected;
  cv::fisheye::projectPoints(object, expected, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), K, dist);
  for (std::size_t i = 0; i < points.size(); ++i) {
    Eigen::Vector2d uv;
    ASSERT_TRUE(projectToPixel(cam, points[i], &uv));
    EXPECT_NEAR(uv.x(), expected[i].x, kReferenceTol);
    EXPECT_NEAR(uv.y(), expected[i].y, kReferenceTol);
  }
}

TEST(CameraModel, UnprojectInvertsProjectOverTheImage) {
  for (const Camera& cam : {radtanCamera(), equidistantCamera()}) {
    double worst = 0.0;
    int checked = 0;
    for (int v = 0; v < cam.resolution[1]; v += 20) {
      for (int u = 0; u < cam.resolution[0]; u += 20) {
        // A fisheye's image corners lie beyond 90 degrees off axis, where no point in front of
        // the camera projects; check up to 75 degrees (distorted angle ~1.3 rad).
        const Eigen::Vector2d d((u - cam.intrinsics[2]) / cam.intrinsics[0],
                                (v - cam.intrinsics[3]) / cam.intrinsics[1]);
        if (cam.distortion_model == DistortionModel::kEquidistant && d.norm() > 1.3) continue;
        ++checked;
        Eigen::Vector2d m;
        ASSERT_TRUE(unprojectPixel(cam, Eigen::Vector2d(u, v), &m)) << u << " " << v;
        Eigen::Vector2d back;
        ASSERT_TRUE(projectToPixel(cam, Eigen::Vector3d(m.x(), m.y(), 1.0), &back));
        worst = std::max(worst, (back - Eigen::Vector2d(u, v)).norm());
      }
    }
    // Newton stops at 1e-12 in normalized units, i.e. ~1e-9 px.
    EXPECT_LT(worst, 1e-8) << toString(cam.distortion_model);
    EXPECT_GT(checked, 500);
  }
}

TEST(CameraModel, BehindTheCameraIsRefused) {
  Eigen::Vector2d uv;
  EXPECT_FALSE(projectToPixel(radtanCamera(), Eigen::Vector3d(0.1, 0.1, -1.0), &uv));
  EXPECT_FALSE(projectToPixel(radtanCamera(), Eigen::Vector3d(0.1, 0.1, 0.0), &uv));
}

// Ceres Jets through the model give the same derivative as central differences, including on
// the optical axis where the equidistant model switches to its series.
TEST(CameraModel, AutodiffMatchesNumericDerivatives) {
  using Jet = ceres::Jet<double, 3>;
  for (const Camera& cam : {radtanCamera(), equidistantCamera()}) {
    for (const Eigen::Vector3d& p : {Eigen::Vector3d(0.3, -0.2, 1.5), Eigen::Vector3d(0, 0, 2)}) {
      Eigen::Matrix<Jet, 3, 1> pj;
      for (int i = 0; i < 3; ++i) pj[i] = Jet(p[i], i);
      const Eigen::Matrix<Jet, 2, 1> uv = projectPoint<Jet>(
          cam.distortion_model, cam.intrinsics.cast<Jet>(), cam.distortion_coeffs.cast<Jet>(), pj);
      for (int i = 0; i < 3; ++i) {
        const Eigen::Vector3d h = Eigen::Vector3d::Unit(i) * 1e-6;
        Eigen::Vector2d plus, minus;
        projectToPixel(cam, p + h, &plus);
        projectToPixel(cam, p - h, &minus);
        const Eigen::Vector2d numeric = (plus - minus) / 2e-6;
        // Central differences: truncation ~1e-12 x third derivative (~1e3 px/m^3 here), round-
        // off ~1e-16 x 500 px / 1e-6 m = 5e-8 px/m; 1e-4 px/m leaves margin.
        EXPECT_NEAR(uv.x().v[i], numeric.x(), 1e-4) << toString(cam.distortion_model);
        EXPECT_NEAR(uv.y().v[i], numeric.y(), 1e-4) << toString(cam.distortion_model);
      }
    }
  }
}

}  // namespace
}  // namespace mvis

namespace mvis {
namespace {

// The estimator's analytic projection Jacobians equal the automatic ones, in the point and in
// all eight intrinsics, for both models, on and off the optical axis.
TEST(CameraModel, AnalyticJacobiansMatchAutodiff) {
  using Jet = ceres::Jet<double, 11>;
  for (const Camera& cam : {radtanCamera(), equidistantCamera()}) {
    const double k[8] = {cam.intrinsics[0],        cam.intrinsics[1],
                         cam.intrinsics[2],        cam.intrinsics[3],
                         cam.distortion_coeffs[0], cam.distortion_coeffs[1],
                         cam.distortion_coeffs[2], cam.distortion_coeffs[3]};
    for (const Eigen::Vector3d& p : {Eigen::Vector3d(0.3, -0.2, 1.5),
                                     Eigen::Vector3d(-0.9, 0.7, 1.1), Eigen::Vector3d(0, 0, 2)}) {
      Eigen::Matrix<Jet, 3, 1> pj;
      Eigen::Matrix<Jet, 4, 1> kj, dj;
      for (int i = 0; i < 3; ++i) pj[i] = Jet(p[i], i);
      for (int i = 0; i < 4; ++i) {
        kj[i] = Jet(k[i], 3 + i);
        dj[i] = Jet(k[4 + i], 7 + i);
      }
      const Eigen::Matrix<Jet, 2, 1> auto_uv = projectPoint<Jet>(cam.distortion_model, kj, dj, pj);
      Eigen::Vector2d uv;
      Eigen::Matrix<double, 2, 3> J_p;
      Eigen::Matrix<double, 2, 8> J_k;
      projectWithJacobians(cam.distortion_model, k, p, &uv, &J_p, &J_k);
      for (int r = 0; r < 2; ++r) {
        // Same arithmetic reordered: agreement to round-off (values up to ~1e3).
        EXPECT_NEAR(uv[r], auto_uv[r].a, 1e-9);
        for (int i = 0; i < 3; ++i) EXPECT_NEAR(J_p(r, i), auto_uv[r].v[i], 1e-7) << r << i;
        for (int i = 0; i < 8; ++i) EXPECT_NEAR(J_k(r, i), auto_uv[r].v[3 + i], 1e-7) << r << i;
      }
    }
  }
}

}  // namespace
}  // namespace mvis
