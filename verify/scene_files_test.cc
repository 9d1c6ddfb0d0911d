// The committed scene files (scenes/*.toml) load as a user loads them, from
// their path, and a built-in scene is the same scene as its file: the same
// grid and the same obstacles, mesh files included (relative mesh paths
// resolve against the scene file's folder in both cases).
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "model/scene.h"

namespace clothbench {
namespace {

namespace fs = std::filesystem;

TEST(SceneFiles, EveryCommittedSceneLoadsFromItsPath) {
  int files = 0;
  for (const auto& entry : fs::directory_iterator(CLOTHBENCH_SCENES_DIR)) {
    if (entry.path().extension() != ".toml") continue;
    ++files;
    EXPECT_NO_THROW(LoadScene(entry.path().string())) << entry.path();
  }
  EXPECT_GE(files, 10);
}

TEST(SceneFiles, BuiltinScenesEqualTheirFiles) {
  for (const char* name : {"round_table", "avatar_drape", "tablecloth"}) {
    const Scene file = LoadScene(std::string(CLOTHBENCH_SCENES_DIR) + "/" + name + ".toml");
    const Scene builtin = BuiltinScene(name);
    EXPECT_EQ(file.grid.nu, builtin.grid.nu) << name;
    ASSERT_EQ(file.obstacles.size(), builtin.obstacles.size()) << name;
    for (std::size_t k = 0; k < file.obstacles.size(); ++k)
      EXPECT_EQ(fs::canonical(file.obstacles[k].shape->file().empty() ? "." : file.obstacles[k].shape->file()),
                fs::canonical(builtin.obstacles[k].shape->file().empty() ? "." : builtin.obstacles[k].shape->file()))
          << name;
  }
}

}  // namespace
}  // namespace clothbench
