// The bloomref command (cli/app.h runs it).
#include "app.h"

int main(int argc, char** argv) {
  return bloomref::cli::run_command_line(std::vector<std::string>(argv + 1, argv + argc));
}
