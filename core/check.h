// Errors as exceptions that carry where they were thrown. Libraries never exit(): callers (the CLI)
// turn an Error into a one-line message and an exit code.
#pragma once

#include <sstream>
#include <stdexcept>
#include <string>

namespace sightmap {

// Any failure caused by the input or the environment (a bad file, a missing device, a full disk).
// what() is a complete sentence meant for the user; file:line is kept separately for logs.
class Error : public std::runtime_error {
 public:
  Error(const std::string& message, const char* file = "", int line = 0);
  const std::string& location() const { return location_; }

 private:
  std::string location_;
};

// A caller passed options or arguments that violate a documented precondition.
class InvalidArgument : public Error {
 public:
  using Error::Error;
};

namespace internal {
// Builds the message lazily: only a failing check pays for formatting.
class MessageBuilder {
 public:
  template <typename T>
  MessageBuilder& operator<<(const T& value) {
    stream_ << value;
    return *this;
  }
  std::string str() const { return stream_.str(); }

 private:
  std::ostringstream stream_;
};
}  // namespace internal

}  // namespace sightmap

// SIGHTMAP_THROW(Error, "cannot open " << path);
#define SIGHTMAP_THROW(ExceptionType, message) \
  throw ExceptionType((::sightmap::internal::MessageBuilder() << message).str(), __FILE__, __LINE__)

// SIGHTMAP_CHECK(cond, "what went wrong and what to do") throws sightmap::Error when cond is false.
#define SIGHTMAP_CHECK(condition, message)        \
  do {                                            \
    if (!(condition)) {                           \
      SIGHTMAP_THROW(::sightmap::Error, message); \
    }                                             \
  } while (false)

// Throws InvalidArgument when an options struct fails its Check().
#define SIGHTMAP_CHECK_OPTIONS(options)                                                            \
  do {                                                                                             \
    std::string sightmap_options_error_;                                                           \
    if (!(options).Check(&sightmap_options_error_)) {                                              \
      SIGHTMAP_THROW(::sightmap::InvalidArgument, "invalid options: " << sightmap_options_error_); \
    }                                                                                              \
  } while (false)
