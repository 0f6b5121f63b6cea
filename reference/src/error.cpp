#include "bloomref/error.h"

namespace bloomref {

InputError::InputError(const std::string& file, const std::string& problem)
    : Error(file.empty() ? problem : file + ": " + problem), file_(file), problem_(problem) {}

}  // namespace bloomref
