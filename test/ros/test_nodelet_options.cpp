// The nodelet's parameters read from a file (mvis_offline --params) by the nodelet's own reader:
// config/mvis.yaml and the device configurations load, their documented values are the code's
// defaults, every key is in doc/ros_api.md, and a wrong key or type is refused by name.
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>

#include "mvis/ros/nodelet_options.h"

namespace mvis {
namespace {

const std::string kSource = MVIS_SOURCE_DIR;

std::string readFile(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string writeTemp(const std::string& name, const std::string& text) {
  const std::string path = ::testing::TempDir() + name;
  std::ofstream(path) << text;
  return path;
}

TEST(NodeletOptions, ConfigFileHoldsTheCodesDefaults) {
  const auto read = NodeletOptions::fromYamlFile(kSource + "/config/mvis.yaml");
  ASSERT_TRUE(read.ok()) << read.status().message();
  const auto documented = read.value().values();
  const auto code = NodeletOptions().values();
  ASSERT_EQ(documented.size(), code.size());
  for (std::size_t i = 0; i < code.size(); ++i) {
    EXPECT_EQ(documented[i], code[i])
        << "config/mvis.yaml says " << documented[i].first << ": " << documented[i].second;
  }
  // And every key is a key of config/mvis.yaml (documented there) and of doc/ros_api.md.
  const std::string config = readFile(kSource + "/config/mvis.yaml");
  const std::string api = readFile(kSource + "/doc/ros_api.md");
  for (const auto& [key, value] : code) {
    if (key != "config_dir") {
      EXPECT_NE(config.find("\n" + key + ":"), std::string::npos) << key;
    }
    EXPECT_NE(api.find("`" + key + "`"), std::string::npos) << key << " is not in doc/ros_api.md";
  }
}

TEST(NodeletOptions, DeviceConfigurationsLoad) {
  for (const std::string device : {"euroc_vi_sensor", "realsense_d435i"}) {
    const auto read = NodeletOptions::fromYamlFile(kSource + "/config/" + device + "/mvis.yaml");
    ASSERT_TRUE(read.ok()) << read.status().message();
    NodeletOptions o = read.value();
    o.config_dir = kSource + "/config/" + device;
    EXPECT_EQ(o.validate(), "") << device;
  }
}

TEST(NodeletOptions, ReadsValuesAndRefusesWrongOnes) {
  const auto read = NodeletOptions::fromYamlFile(writeTemp(
      "params_ok.yaml",
      "estimate_intrinsics: true\nmin_tags: 4\ntag_decimate: 2\nhold: [cam1.intrinsics]\n"));
  ASSERT_TRUE(read.ok()) << read.status().message();
  EXPECT_TRUE(read.value().estimatorOptions().estimate_intrinsics);
  EXPECT_EQ(read.value().estimatorOptions().min_tags, 4);
  EXPECT_EQ(read.value().frontendOptions().detector.decimate, 2.0);
  EXPECT_EQ(read.value().hold, std::vector<std::string>{"cam1.intrinsics"});
  EXPECT_TRUE(read.value().estimatorOptions().estimate_extrinsics);  // the default

  const std::string typo = writeTemp("params_typo.yaml", "estimate_intrinsic: true\n");
  const auto refused = NodeletOptions::fromYamlFile(typo);
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.status().message().find(typo), std::string::npos);
  EXPECT_NE(refused.status().message().find("unknown parameter 'estimate_intrinsic'"),
            std::string::npos)
      << refused.status().message();

  const auto wrong = NodeletOptions::fromYamlFile(writeTemp("params_type.yaml", "min_tags: two\n"));
  ASSERT_FALSE(wrong.ok());
  EXPECT_NE(wrong.status().message().find("'min_tags' has a value of the wrong type"),
            std::string::npos)
      << wrong.status().message();

  EXPECT_FALSE(NodeletOptions::fromYamlFile(kSource + "/no/such/file.yaml").ok());
}

}  // namespace
}  // namespace mvis
