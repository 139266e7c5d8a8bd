// Error reporting without exceptions across the core's public interface.
//
// A Status is either ok or carries one human-readable message. Messages that come from a
// configuration file name the file, the sensor and the key: "FILE: SENSOR: KEY: problem".
#pragma once

#include <optional>
#include <string>
#include <utility>

namespace mvis {

class Status {
 public:
  static Status Ok() { return Status(); }
  static Status Error(std::string message) { return Status(std::move(message)); }

  bool ok() const { return !message_.has_value(); }
  explicit operator bool() const { return ok(); }
  // Empty for an ok status.
  const std::string& message() const {
    static const std::string kEmpty;
    return message_ ? *message_ : kEmpty;
  }

 private:
  Status() = default;
  explicit Status(std::string message) : message_(std::move(message)) {}
  std::optional<std::string> message_;
};

// A value or the Status saying why there is none.
template <typename T>
class StatusOr {
 public:
  StatusOr(T value) : value_(std::move(value)), status_(Status::Ok()) {}  // NOLINT
  StatusOr(Status status) : status_(std::move(status)) {}                 // NOLINT

  bool ok() const { return value_.has_value(); }
  const Status& status() const { return status_; }
  const T& value() const& { return *value_; }
  T& value() & { return *value_; }
  // By value, so that `for (auto& x : f().value())` cannot dangle.
  T value() && { return std::move(*value_); }

 private:
  std::optional<T> value_;
  Status status_;
};

}  // namespace mvis
