#include "report.h"

namespace bloomref::cli {
void write_report(const std::string&, const std::string&, const std::string&, const Plan&,
                  const StageTrace&, const parity::ParityResult&, const std::string&) {}
}  // namespace bloomref::cli
