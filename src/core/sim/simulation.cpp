#include "mvis/sim/simulation.h"

namespace mvis {

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

  std::vector<StampedPose> truth_trajectory;
  for (std::size_t i = 0; i < truth.inertial.size(); ++i) {
    ImuSimulationOptions options;
    options.noise = config.imu_noise;
    options.biases = config.imu_noise;
    options.seed = config.seed * 1000 + i;
    const auto samples = simulateImu(truth.inertial[i], base, t0, t0, end, options);
    for (const auto& s : samples) sink->imu(i, s);
    if (i == 0) {
      for (const auto& s : samples) {
        truth_trajectory.emplace_back(s.stamp_ns, base(toSeconds(s.stamp_ns - t0)).T_G_I);
      }
    }
  }

  std::unique_ptr<TagBoardRenderer> renderer;
  if (config.camera_output == CameraOutput::kImages) {
    auto created = TagBoardRenderer::create(*truth.target, config.board);
    if (!created.ok()) return created.status();
    renderer = std::move(created).value();
  }
  for (std::size_t c = 0; c < truth.cameras.size(); ++c) {
    const std::uint64_t seed = config.seed * 1000 + 100 + c;
    if (config.camera_output == CameraOutput::kDetections) {
      for (const auto& frame : simulateTagFrames(truth, c, config.camera_rate_hz[c], base, t0, t0,
                                                 end, config.pixel_noise_px, seed)) {
        sink->tagFrame(frame);
      }
      continue;
    }
    // The sample pattern is fixed per camera; the noise changes per frame.
    const CameraRays rays(truth.cameras[c], config.supersample, static_cast<std::uint32_t>(seed));
    const TimeNs period = fromSeconds(1.0 / config.camera_rate_hz[c]);
    RenderOptions render;
    render.supersample = config.supersample;
    render.noise_sigma = config.image_noise_sigma;
    render.blur_sigma = config.image_blur_px;
    std::uint32_t frame_index = 0;
    for (TimeNs stamp = t0; stamp <= end; stamp += period, ++frame_index) {
      render.seed = static_cast<std::uint32_t>(seed * 100000 + frame_index);
      const SE3 T_G_C = cameraPose(truth, c, base, t0, stamp);
      sink->image(c, stamp, renderer->render(rays, T_G_C, render, config.threads));
    }
  }
  return truth_trajectory;
}

}  // namespace mvis
