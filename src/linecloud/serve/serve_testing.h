// What the service's tests share: their fixtures (serve_fixtures.h), and
// `linecloud serve` run as a child process.
#pragma once

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "linecloud/serve/serve_fixtures.h"
#include "linecloud/util/file.h"

namespace linecloud {

// The real binary (LINECLOUD_BINARY) run with `args` (after its name), its
// standard error in `err_path`; port() once it listens (0 if it never did).
class ServedBinary {
 public:
  ServedBinary(std::vector<std::string> args, std::string err_path) : err_(std::move(err_path)) {
    args.insert(args.begin(), "linecloud");
    pid_ = ::fork();
    if (pid_ == 0) {
      const int fd = ::open(err_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
      ::dup2(fd, 2);
      std::vector<char*> argv;
      for (std::string& a : args) argv.push_back(a.data());
      argv.push_back(nullptr);
      ::execv(LINECLOUD_BINARY, argv.data());
      ::_exit(127);
    }
    for (int i = 0; i < 400 && port_ == 0 && Alive(); ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(25));
      const std::string text = ReadFileToString(err_);
      const std::string key = "listening on http://127.0.0.1:";
      if (const size_t at = text.find(key); at != std::string::npos) {
        port_ = std::atoi(text.c_str() + at + key.size());
      }
    }
  }
  ServedBinary(const ServedBinary&) = delete;
  ServedBinary& operator=(const ServedBinary&) = delete;
  ~ServedBinary() {
    if (!exited_) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
  }
  int port() const { return port_; }
  pid_t pid() const { return pid_; }
  std::string err() const { return ReadFileToString(err_); }
  // Still running (no crash).
  bool Alive() {
    if (!exited_ && ::waitpid(pid_, &status_, WNOHANG) == pid_) exited_ = true;
    return !exited_;
  }
  // Waits for the process to end; its wait status.
  int Wait() {
    if (!exited_ && ::waitpid(pid_, &status_, 0) == pid_) exited_ = true;
    return status_;
  }

 private:
  std::string err_;
  pid_t pid_ = -1;
  int port_ = 0;
  bool exited_ = false;
  int status_ = 0;
};

}  // namespace linecloud
