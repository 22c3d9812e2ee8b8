// One writer per model: a second writer is refused with who holds the model, readers are not,
// and the lock goes with its holder (closed, or killed).
#include "store/writer_lock.h"

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <functional>
#include <optional>
#include <string>

#include <gtest/gtest.h>

#include "core/check.h"
#include "store/model.h"
#include "tests/test_data.h"

namespace sightmap::store {
namespace {

std::string ErrorOf(const std::function<void()>& open) {
  try {
    open();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(WriterLock, ASecondWriterIsToldWhoHoldsTheModel) {
  const std::string path = testing::MakeTempDir("writer-lock") + "/model.db";
  std::optional<Model> writer(Model::Open(path));
  const std::string error = ErrorOf([&] { Model::Open(path); });
  EXPECT_NE(error.find("is in use by sightmap pid " + std::to_string(getpid()) + " since "),
            std::string::npos)
      << error;
  // Readers work beside the writer.
  ModelOptions read_only;
  read_only.read_only = true;
  EXPECT_EQ(Model::Open(path, read_only).NumKeyframes(), 0);
  // Closed, the model takes a writer again.
  writer.reset();
  EXPECT_EQ(ErrorOf([&] { Model::Open(path); }), "");
}

TEST(WriterLock, AKilledWriterLeavesTheModelFree) {
  const std::string path = testing::MakeTempDir("writer-lock-killed") + "/model.db";
  Model::Open(path);  // created, then closed
  int ready[2];
  ASSERT_EQ(pipe(ready), 0);
  const pid_t child = fork();
  if (child == 0) {
    const Model held = Model::Open(path);
    const char byte = 1;
    [[maybe_unused]] const ssize_t written = write(ready[1], &byte, 1);
    pause();
    _exit(0);
  }
  char byte = 0;
  ASSERT_EQ(read(ready[0], &byte, 1), 1);
  const std::string error = ErrorOf([&] { Model::Open(path); });
  EXPECT_NE(error.find("in use by sightmap pid " + std::to_string(child)), std::string::npos)
      << error;
  kill(child, SIGKILL);
  waitpid(child, nullptr, 0);
  EXPECT_EQ(ErrorOf([&] { Model::Open(path); }), "")
      << "the kernel released the killed writer's lock";
  close(ready[0]);
  close(ready[1]);
}

}  // namespace
}  // namespace sightmap::store
