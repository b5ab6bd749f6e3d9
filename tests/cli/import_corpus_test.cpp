// Every model file of Debian's assimp-testmodels through `cpvs plan`, as a new user would
// try them: each plans or gets a clear error (exit 2, a "cpvs: " line naming the file),
// none ends by a signal or a hang: the command line imports in a limited child process
// (cpvs/scene/isolated_import.h). And an importer that crashes, hangs or allocates without
// bound costs a clear error too.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <filesystem>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "process_testing.h"

namespace cpvs {
namespace {

namespace fs = std::filesystem;

const char* const kModels = "/usr/share/assimp/models";  // deploy/setup.sh installs assimp-testmodels

testing::CommandResult plan(const std::string& file, const std::string& environment = "") {
  return testing::runShell(environment + " timeout 120 '" CPVS_CLI "' plan '" + file +
                           "' --sun-dir 0.3,-1,0.4 -r 64 2>&1");
}

TEST(ImportCorpus, EveryTestModelPlansOrGetsAClearError) {
  ASSERT_TRUE(fs::is_directory(kModels)) << kModels << " is missing: run deploy/setup.sh (assimp-testmodels)";
  std::vector<std::string> files;
  for (const auto& e : fs::recursive_directory_iterator(kModels))
    if (e.is_regular_file()) files.push_back(e.path().string());
  std::sort(files.begin(), files.end());
  ASSERT_GT(files.size(), 400u);
  std::atomic<size_t> next{0}, planned{0}, refused{0};
  std::mutex failures;
  std::vector<std::string> wrong;
  auto work = [&] {
    for (size_t i; (i = next++) < files.size();) {
      // 20 s a file at most: a file that hangs the importer is stopped by its limit.
      const testing::CommandResult r = plan(files[i], "CPVS_IMPORT_SECONDS=20");
      if (r.status == 0) {
        ++planned;
        continue;
      }
      const bool clear = r.status == 2 && r.out.find("cpvs: ") != std::string::npos;
      if (clear) {
        ++refused;
        continue;
      }
      std::lock_guard lock(failures);
      wrong.push_back(files[i] + ": exit " + std::to_string(r.status) + ": " + r.out.substr(0, 400));
    }
  };
  std::thread other(work);
  work();
  other.join();
  for (const std::string& w : wrong) ADD_FAILURE() << w;
  std::printf("%zu model files: %zu planned, %zu refused with a clear error\n", files.size(), planned.load(), refused.load());
  EXPECT_GT(planned.load(), files.size() / 2);
}

// The importer's failures, made on purpose in the child (CPVS_FAILPOINT): a crash, a hang
// past CPVS_IMPORT_SECONDS and a memory hog past CPVS_IMPORT_MEMORY_MB each give a clear
// error and exit 2; the same file plans without them; an importer that tries to escape
// (a socket, a file, a process, a program) is refused each.
TEST(ImportCorpus, AnImporterThatCrashesHangsOrHogsCostsAClearError) {
  const std::string file = std::string(kModels) + "/OBJ/box.obj";
  ASSERT_TRUE(fs::exists(file));
  EXPECT_EQ(plan(file).status, 0);
  for (const auto& [environment, says] :
       std::vector<std::pair<std::string, std::string>>{{"CPVS_FAILPOINT=import-crash", "crashed on the file"},
                                                        {"CPVS_FAILPOINT=import-hang CPVS_IMPORT_SECONDS=1", "longer than 1 s"},
                                                        {"CPVS_FAILPOINT=import-hog CPVS_IMPORT_MEMORY_MB=512", "more than its 512 MiB"}}) {
    const testing::CommandResult r = plan(file, environment);
    EXPECT_EQ(r.status, 2) << environment << ": " << r.out;
    EXPECT_NE(r.out.find(says), std::string::npos) << environment << ": " << r.out;
  }
  // Code run by a hostile file inside the importer is in the sandbox: no socket, no file
  // made, no process, no program.
  const testing::CommandResult escape = plan(file, "CPVS_FAILPOINT=import-escape");
  EXPECT_NE(escape.status, 0) << escape.out;
  EXPECT_NE(escape.out.find("escape: socket refused, file refused, fork refused, exec refused"), std::string::npos)
      << escape.out;
  for (const auto& entry : fs::directory_iterator("/tmp"))
    EXPECT_EQ(entry.path().filename().string().rfind("cpvs-import-escape-", 0), std::string::npos) << entry.path();
  const testing::CommandResult bad = plan(file, "CPVS_IMPORT_SECONDS=-1");
  EXPECT_EQ(bad.status, 2);
  EXPECT_NE(bad.out.find("CPVS_IMPORT_SECONDS"), std::string::npos) << bad.out;
}

}  // namespace
}  // namespace cpvs
