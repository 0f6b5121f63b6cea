// bloomref — the errors the library reports. The CLI maps them to exit codes:
// InputError and ParamError -> 2 (bad input or usage), GlUnavailable -> 3.
#pragma once

#include <stdexcept>
#include <string>

namespace bloomref {

/// Base of every error bloomref throws on purpose.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A parameter is out of its domain; the message names the parameter, its value and the rule.
class ParamError : public Error {
 public:
  using Error::Error;
};

/// A file or image cannot be used; the message names the file (when there is one) and the problem.
class InputError : public Error {
 public:
  InputError(const std::string& file, const std::string& problem);
  const std::string& file() const { return file_; }
  const std::string& problem() const { return problem_; }

 private:
  std::string file_;
  std::string problem_;
};

}  // namespace bloomref
