// mvis_simulate --rig DIR [--sim FILE] --output DIR [--detections | --compressed]
// Simulates the rig described in DIR (the truth: kalibr_imu_chain.yaml, kalibr_imucam_chain.yaml,
// aprilgrid.yaml) as the simulation yaml says (default DIR/sim.yaml), and writes OUTPUT/sim.bag,
// OUTPUT/truth/ and OUTPUT/config/ (the perturbed initial guess). See
// include/mvis/ros/simulation_bag.h.
#include <cstdio>
#include <cstring>
#include <string>

#include "mvis/rig/rig_io.h"
#include "mvis/ros/simulation_bag.h"

namespace {

int usage(const char* message) {
  std::fprintf(stderr,
               "%s\nusage: mvis_simulate --rig DIR [--sim FILE] --output DIR\n"
               "                     [--detections | --compressed]\n"
               "  --rig DIR       the true rig (kalibr_imu_chain.yaml, kalibr_imucam_chain.yaml,\n"
               "                  aprilgrid.yaml)\n"
               "  --sim FILE      simulation yaml (default DIR/sim.yaml)\n"
               "  --output DIR    where sim.bag, truth/ and config/ go\n"
               "  --detections    tag detections instead of rendered images (fast)\n"
               "  --compressed    the images PNG-compressed (sensor_msgs/CompressedImage on\n"
               "                  <camera topic>/compressed), as rigs usually record them\n",
               message);
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  std::string rig_dir, sim_file, output_dir;
  bool detections = false, compressed = false;
  for (int i = 1; i < argc; ++i) {
    const auto value = [&](std::string* out) {
      if (i + 1 >= argc) return false;
      *out = argv[++i];
      return true;
    };
    if (std::strcmp(argv[i], "--rig") == 0) {
      if (!value(&rig_dir)) return usage("--rig needs a directory");
    } else if (std::strcmp(argv[i], "--sim") == 0) {
      if (!value(&sim_file)) return usage("--sim needs a file");
    } else if (std::strcmp(argv[i], "--output") == 0) {
      if (!value(&output_dir)) return usage("--output needs a directory");
    } else if (std::strcmp(argv[i], "--detections") == 0) {
      detections = true;
    } else if (std::strcmp(argv[i], "--compressed") == 0) {
      compressed = true;
    } else {
      return usage((std::string("unknown argument ") + argv[i]).c_str());
    }
  }
  if (rig_dir.empty() || output_dir.empty()) return usage("--rig and --output are required");
  if (detections && compressed) return usage("--detections and --compressed exclude each other");
  if (sim_file.empty()) sim_file = rig_dir + "/sim.yaml";

  const auto rig = mvis::loadRig(rig_dir);
  if (!rig.ok()) {
    std::fprintf(stderr, "mvis_simulate: %s\n", rig.status().message().c_str());
    return 1;
  }
  auto config = mvis::loadSimulationConfig(sim_file, rig.value().cameras.size());
  if (!config.ok()) {
    std::fprintf(stderr, "mvis_simulate: %s\n", config.status().message().c_str());
    return 1;
  }
  if (detections) config.value().camera_output = mvis::CameraOutput::kDetections;
  const auto summary =
      mvis::writeSimulationBag(rig.value(), config.value(), output_dir, compressed);
  if (!summary.ok()) {
    std::fprintf(stderr, "mvis_simulate: %s\n", summary.status().message().c_str());
    return 1;
  }
  std::printf(
      "mvis_simulate: %.1f s of %s motion in %.1f s: %zu IMU messages, %zu camera "
      "messages%s -> %s/sim.bag\n",
      config.value().duration_s, mvis::toString(config.value().motion.kind),
      summary.value().seconds, summary.value().imu_messages, summary.value().camera_messages,
      detections ? (" (" + std::to_string(summary.value().tags) + " tags)").c_str() : "",
      output_dir.c_str());
  return 0;
}
