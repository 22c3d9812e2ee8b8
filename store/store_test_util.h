// Test helpers shared by the store suites: run code in a forked child and collect its outcome.
#pragma once

#include <sys/wait.h>
#include <unistd.h>

#include <functional>
#include <string>

#include "core/check.h"

namespace sightmap::testing {

struct ChildOutcome {
  int exit_code = -1;   // -1 when killed by a signal
  int signal = 0;       // the signal that ended it, or 0
  std::string message;  // what the child wrote to its pipe (an Error's what())
};

// Runs `body` in a forked child. A sightmap::Error thrown by `body` becomes exit code 3 and its
// message; normal return is exit code 0. The child never returns into gtest.
inline ChildOutcome RunInChild(const std::function<void()>& body) {
  int fds[2];
  if (pipe(fds) != 0) return {};
  const pid_t pid = fork();
  if (pid == 0) {
    close(fds[0]);
    int code = 0;
    std::string message;
    try {
      body();
    } catch (const Error& e) {
      message = e.what();
      code = 3;
    } catch (const std::exception& e) {
      message = std::string("unexpected: ") + e.what();
      code = 4;
    }
    if (!message.empty()) {
      const ssize_t written = write(fds[1], message.data(), message.size());
      (void)written;
    }
    close(fds[1]);
    _exit(code);
  }
  close(fds[1]);
  ChildOutcome outcome;
  char buffer[4096];
  ssize_t n;
  while ((n = read(fds[0], buffer, sizeof(buffer))) > 0) {
    outcome.message.append(buffer, static_cast<size_t>(n));
  }
  close(fds[0]);
  int status = 0;
  waitpid(pid, &status, 0);
  if (WIFEXITED(status)) outcome.exit_code = WEXITSTATUS(status);
  if (WIFSIGNALED(status)) outcome.signal = WTERMSIG(status);
  return outcome;
}

}  // namespace sightmap::testing
