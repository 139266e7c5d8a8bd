// mvis_render_board CONFIG_DIR CAMERA DISTANCE_M OUT.pgm [NOISE_SIGMA]
// Renders the rig's aprilgrid.yaml board, seen square-on from DISTANCE_M metres by camera
// CAMERA (index into kalibr_imucam_chain.yaml; its pinhole intrinsics and resolution, no
// distortion), to an 8-bit PGM. For checking a target setup and for test fixtures.
#include <cstdio>
#include <cstdlib>
#include <opencv2/imgcodecs.hpp>
#include <string>

#include "mvis/rig/rig_io.h"
#include "mvis/sim/tag_renderer.h"

int main(int argc, char** argv) {
  if (argc < 5 || argc > 6) {
    std::fprintf(stderr,
                 "usage: mvis_render_board CONFIG_DIR CAMERA DISTANCE_M OUT.pgm "
                 "[NOISE_SIGMA]\n");
    return 2;
  }
  const auto rig = mvis::loadRig(argv[1]);
  if (!rig.ok()) {
    std::fprintf(stderr, "%s\n", rig.status().message().c_str());
    return 1;
  }
  const std::size_t camera = std::strtoul(argv[2], nullptr, 10);
  const double distance = std::atof(argv[3]);
  if (camera >= rig.value().cameras.size() || !rig.value().target || !(distance > 0.0)) {
    std::fprintf(stderr, "need an existing camera, an aprilgrid.yaml and a positive distance\n");
    return 1;
  }
  const mvis::Camera& cam = rig.value().cameras[camera];
  const mvis::AprilGrid& grid = *rig.value().target;
  auto renderer = mvis::TagBoardRenderer::create(grid);
  if (!renderer.ok()) {
    std::fprintf(stderr, "%s\n", renderer.status().message().c_str());
    return 1;
  }
  // Camera on the board's normal through its centre, x along the board's x, y along its -y.
  const double pitch = (1.0 + grid.tag_spacing) * grid.tag_size;
  const Eigen::Vector3d centre(0.5 * (grid.tag_cols * pitch - grid.tag_spacing * grid.tag_size),
                               0.5 * (grid.tag_rows * pitch - grid.tag_spacing * grid.tag_size),
                               0.0);
  Eigen::Matrix3d R_board_cam;
  R_board_cam << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  const mvis::SE3 T_board_cam(R_board_cam, centre + Eigen::Vector3d(0, 0, distance));
  mvis::RenderOptions options;
  options.noise_sigma = argc == 6 ? std::atof(argv[5]) : 0.0;
  const cv::Mat image = renderer.value()->render(
      cam.resolution[0], cam.resolution[1],
      mvis::pinholeToBoard(cam.intrinsics, T_board_cam.inverse()), options);
  if (!cv::imwrite(argv[4], image)) {
    std::fprintf(stderr, "%s: cannot write\n", argv[4]);
    return 1;
  }
  return 0;
}
