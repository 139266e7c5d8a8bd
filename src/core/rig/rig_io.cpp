// aprilgrid.yaml, and loading/saving a whole configuration directory.
#include "mvis/rig/rig_io.h"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "yaml_reader.h"

namespace mvis {
namespace {

namespace fs = std::filesystem;

// The whole file, or nullopt if it cannot be read.
std::optional<std::string> readFile(const fs::path& path) {
  std::ifstream in(path);
  if (!in) return std::nullopt;
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

Status writeFile(const fs::path& path, const std::string& text) {
  std::ofstream out(path);
  out << text;
  out.close();
  if (!out) return Status::Error(path.string() + ": cannot write");
  return Status::Ok();
}

}  // namespace

StatusOr<AprilGrid> parseAprilGrid(const std::string& yaml_text, const std::string& path) {
  return rig_io::guardedParse(path, [&] {
    const rig_io::EntryReader entry(rig_io::parseYamlText(yaml_text, path), path, "");
    entry.rejectUnknownKeys(
        {"target_type", "tagCols", "tagRows", "tagSize", "tagSpacing", "tagFamily"});
    const std::string type = entry.text("target_type");
    if (type != "aprilgrid") {
      entry.fail("target_type", "unsupported target type '" + type + "' (expected aprilgrid)");
    }
    AprilGrid grid;
    grid.tag_cols = entry.positiveInteger("tagCols");
    grid.tag_rows = entry.positiveInteger("tagRows");
    grid.tag_size = entry.positiveNumber("tagSize");
    grid.tag_spacing = entry.number("tagSpacing");
    if (grid.tag_spacing < 0.0) entry.fail("tagSpacing", "must not be negative");
    grid.tag_family = entry.text("tagFamily", "tag36h11");
    const auto& families = supportedTagFamilies();
    if (std::find(families.begin(), families.end(), grid.tag_family) == families.end()) {
      entry.fail("tagFamily", "unknown tag family '" + grid.tag_family + "'");
    }
    return grid;
  });
}

std::string aprilGridToYaml(const AprilGrid& grid) {
  std::ostringstream out;
  out << "# Tag board (Kalibr aprilgrid). Format: doc/conventions.md\n";
  out << "target_type: aprilgrid\n";
  out << "tagCols: " << grid.tag_cols << "\n";
  out << "tagRows: " << grid.tag_rows << "\n";
  out << "tagSize: " << rig_io::formatNumber(grid.tag_size) << "\n";
  out << "tagSpacing: " << rig_io::formatNumber(grid.tag_spacing) << "\n";
  out << "tagFamily: " << grid.tag_family << "\n";
  return out.str();
}

RigFiles RigFiles::in(const std::string& directory, const std::string& imu_chain,
                      const std::string& cam_chain, const std::string& target) {
  const auto resolve = [&](const std::string& name, const char* fallback) {
    const fs::path given(name.empty() ? fallback : name);
    return (given.is_absolute() ? given : fs::path(directory) / given).string();
  };
  return {resolve(imu_chain, kImuChainFile), resolve(cam_chain, kCamChainFile),
          resolve(target, kAprilGridFile)};
}

StatusOr<Rig> loadRig(const std::string& directory, std::vector<std::string>* warnings) {
  if (!fs::is_directory(fs::path(directory))) {
    return Status::Error(directory +
                         ": not a directory (expected a configuration directory "
                         "holding " +
                         kImuChainFile + " and " + kCamChainFile + ")");
  }
  return loadRig(RigFiles::in(directory), warnings);
}

StatusOr<Rig> loadRig(const RigFiles& files, std::vector<std::string>* warnings) {
  Rig rig;
  const fs::path imu_path = files.imu_chain;
  const auto imu_text = readFile(imu_path);
  if (!imu_text) return Status::Error(imu_path.string() + ": cannot read the file");
  auto inertial = parseImuChain(*imu_text, imu_path.string(), warnings);
  if (!inertial.ok()) return inertial.status();
  rig.inertial = std::move(inertial).value();

  const fs::path cam_path = files.cam_chain;
  const auto cam_text = readFile(cam_path);
  if (!cam_text) return Status::Error(cam_path.string() + ": cannot read the file");
  auto cameras = parseCamChain(*cam_text, cam_path.string(), warnings);
  if (!cameras.ok()) return cameras.status();
  rig.cameras = std::move(cameras).value();

  // A topic shared by an inertial sensor and a camera.
  std::map<std::string, std::string> topics;
  for (const auto& s : rig.inertial) topics.emplace(s.rostopic, s.name);
  for (const auto& c : rig.cameras) {
    const auto it = topics.find(c.rostopic);
    if (it != topics.end()) {
      return Status::Error(cam_path.string() + ": " + c.name + ": rostopic: '" + c.rostopic +
                           "' is already used by " + it->second + " in " +
                           imu_path.filename().string());
    }
  }

  const fs::path grid_path = files.target;
  if (!grid_path.empty() && fs::exists(grid_path)) {
    const auto grid_text = readFile(grid_path);
    if (!grid_text) return Status::Error(grid_path.string() + ": cannot read the file");
    auto grid = parseAprilGrid(*grid_text, grid_path.string());
    if (!grid.ok()) return grid.status();
    rig.target = grid.value();
  }
  return rig;
}

Status saveRig(const Rig& rig, const std::string& directory) {
  const fs::path dir(directory);
  std::error_code error;
  fs::create_directories(dir, error);
  if (error) return Status::Error(directory + ": cannot create the directory: " + error.message());
  Status status = writeFile(dir / kImuChainFile, imuChainToYaml(rig));
  if (!status.ok()) return status;
  status = writeFile(dir / kCamChainFile, camChainToYaml(rig));
  if (!status.ok()) return status;
  if (rig.target) return writeFile(dir / kAprilGridFile, aprilGridToYaml(*rig.target));
  return Status::Ok();
}

}  // namespace mvis
