#include "mvis/sim/simulation.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "mvis/camera/camera_model.h"
#include "mvis/sim/coverage_renderer.h"

namespace mvis {
namespace {

// The recording in pieces between the sensors' moves: each piece's start (base clock) and the rig
// then.
struct Piece {
  TimeNs start;
  Rig rig;
};

StatusOr<std::vector<Piece>> pieces(const Rig& truth, const SimulationConfig& config) {
  std::vector<double> times = {0.0};
  for (const SensorMove& m : config.moves) {
    if (m.at_s > 0.0) times.push_back(m.at_s);
  }
  std::sort(times.begin(), times.end());
  times.erase(std::unique(times.begin(), times.end()), times.end());
  std::vector<Piece> out;
  for (double t : times) {
    std::vector<SensorMove> done;
    for (const SensorMove& m : config.moves) {
      if (m.at_s <= t) done.push_back(m);
    }
    auto rig = movedRig(truth, done);
    if (!rig.ok()) return rig.status();
    out.push_back({config.start_ns + fromSeconds(t), std::move(rig).value()});
  }
  return out;
}

// The piece a sample stamped t falls in.
const Rig& rigAt(const std::vector<Piece>& pieces, TimeNs t) {
  std::size_t k = 0;
  while (k + 1 < pieces.size() && t >= pieces[k + 1].start) ++k;
  return pieces[k].rig;
}

}  // namespace

StatusOr<std::vector<StampedPose>> runSimulation(const Rig& truth, const SimulationConfig& config,
                                                 SimulationSink* sink) {
  if (!truth.target) return Status::Error("the rig has no aprilgrid.yaml: nothing to look at");
  if (config.camera_rate_hz.size() != truth.cameras.size()) {
    return Status::Error("camera_rate_hz has " + std::to_string(config.camera_rate_hz.size()) +
                         " rates for " + std::to_string(truth.cameras.size()) + " cameras");
  }
  const SinusoidTrajectory trajectory = makeBoardTrajectory(truth, config.motion);
  const TrajectoryFunction base = [&trajectory](double t) { return trajectory.evaluate(t); };
  const TimeNs t0 = config.start_ns;
  const TimeNs end = t0 + fromSeconds(config.duration_s);
  const auto made = pieces(truth, config);
  if (!made.ok()) return made.status();
  const std::vector<Piece>& moved = made.value();

  std::vector<StampedPose> truth_trajectory;
  for (std::size_t i = 0; i < truth.inertial.size(); ++i) {
    ImuSimulationOptions options;
    options.noise = config.imu_noise;
    options.biases = config.imu_noise;
    options.seed = config.seed * 1000 + i;
    // Each piece's sensor over the whole recording with the same noise; its own span taken.
    std::vector<std::vector<ImuSample>> per_piece;
    for (const Piece& piece : moved) {
      per_piece.push_back(simulateImu(piece.rig.inertial[i], base, t0, t0, end, options));
    }
    const auto& samples = per_piece.front();
    for (std::size_t n = 0; n < samples.size(); ++n) {
      std::size_t k = 0;
      while (k + 1 < moved.size() && samples[n].stamp_ns >= moved[k + 1].start) ++k;
      sink->imu(i, per_piece[k][n]);
    }
    if (i == 0) {
      for (const auto& s : samples) {
        truth_trajectory.emplace_back(s.stamp_ns, base(toSeconds(s.stamp_ns - t0)).T_G_I);
      }
    }
  }

  std::unique_ptr<TagBoardRenderer> renderer;
  if (config.camera_output == CameraOutput::kImages && !config.coverage_renderer) {
    auto created = TagBoardRenderer::create(*truth.target, config.board);
    if (!created.ok()) return created.status();
    renderer = std::move(created).value();
  }
  for (std::size_t c = 0; c < truth.cameras.size(); ++c) {
    const std::uint64_t seed = config.seed * 1000 + 100 + c;
    if (config.camera_output == CameraOutput::kDetections) {
      // Piece by piece on the camera's frame grid, each with its own noise stream.
      const TimeNs period = fromSeconds(1.0 / config.camera_rate_hz[c]);
      for (std::size_t k = 0; k < moved.size(); ++k) {
        const TimeNs from = t0 + (moved[k].start - t0 + period - 1) / period * period;
        const TimeNs to = k + 1 < moved.size() ? moved[k + 1].start - 1 : end;
        for (const auto& frame :
             simulateTagFrames(moved[k].rig, c, config.camera_rate_hz[c], base, t0, from, to,
                               config.pixel_noise_px, seed + 7919 * k)) {
          sink->tagFrame(frame);
        }
      }
      continue;
    }
    const TimeNs period = fromSeconds(1.0 / config.camera_rate_hz[c]);
    if (config.coverage_renderer) {
      CoverageOptions options;
      options.width = truth.cameras[c].resolution[0];
      options.height = truth.cameras[c].resolution[1];
      options.kalibr_squares = config.board == BoardKind::kKalibrGrid;
      options.blur_sigma = config.image_blur_px;
      options.gamma = config.image_gamma;
      options.vignetting = config.image_vignetting;
      options.noise_sigma = config.image_noise_sigma;
      options.subdivisions = 4;  // the lens bends a tag cell's sides by well under 0.01 px
      std::uint32_t frame_index = 0;
      for (TimeNs stamp = t0; stamp <= end; stamp += period, ++frame_index) {
        options.seed = static_cast<std::uint32_t>(seed * 100000 + frame_index);
        const Rig& rig = rigAt(moved, stamp);
        const SE3 T_C_G = cameraPose(rig, c, base, t0, stamp).inverse();
        const Camera& camera = rig.cameras[c];
        auto image = renderByCoverage(
            *truth.target,
            [&](const Eigen::Vector2d& board, Eigen::Vector2d* pixel) {
              // Only near the field of view (undistorted within half an image of it): beyond,
              // a polynomial distortion folds points back into the image.
              const Eigen::Vector3d p = T_C_G * Eigen::Vector3d(board.x(), board.y(), 0.0);
              const Eigen::Vector4d& k = camera.intrinsics;
              const double u = k[0] * p.x() / p.z() + k[2], v = k[1] * p.y() / p.z() + k[3];
              if (!(std::abs(u - 0.5 * options.width) < options.width &&
                    std::abs(v - 0.5 * options.height) < options.height)) {
                return false;
              }
              return projectToPixel(camera, p, pixel);
            },
            options);
        if (!image.ok()) return image.status();
        sink->image(c, stamp, image.value());
      }
      continue;
    }
    // The sample pattern is fixed per camera; the noise changes per frame.
    const CameraRays rays(truth.cameras[c], config.supersample, static_cast<std::uint32_t>(seed));
    RenderOptions render;
    render.supersample = config.supersample;
    render.noise_sigma = config.image_noise_sigma;
    render.blur_sigma = config.image_blur_px;
    std::uint32_t frame_index = 0;
    for (TimeNs stamp = t0; stamp <= end; stamp += period, ++frame_index) {
      render.seed = static_cast<std::uint32_t>(seed * 100000 + frame_index);
      const SE3 T_G_C = cameraPose(rigAt(moved, stamp), c, base, t0, stamp);
      sink->image(c, stamp, renderer->render(rays, T_G_C, render, config.threads));
    }
  }
  return truth_trajectory;
}

}  // namespace mvis
