#include "client/common/cli_main.h"

#include <algorithm>
#include <iostream>
#include <string>
#include <vector>

#include "client/common/exit_codes.h"
#include "core/error.h"
#include "core/io/suggest.h"

namespace invr::cli {

int runCommandLine(CLI::App& app, int argc, char** argv, const char* program, const int& exitCode) {
  // CLI11 answers an unknown first word with "a subcommand is required": name it instead.
  if (argc > 1 && argv[1][0] != '-') {
    std::vector<std::string> names;
    for (const CLI::App* sub : app.get_subcommands({})) names.push_back(sub->get_name());
    if (std::find(names.begin(), names.end(), argv[1]) == names.end()) {
      std::string all;
      for (const auto& n : names) all += (all.empty() ? "" : ", ") + n;
      std::cerr << program << ": unknown command '" << argv[1] << "'" << didYouMean(argv[1], names) << " (the commands are: " << all
                << "; " << program << " --help)\n";
      return exit_code::kUsage;
    }
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return exit_code::kUsage;
  } catch (const ExitError& e) {
    if (*e.what()) std::cerr << program << ": " << e.what() << "\n";
    return e.code;
  } catch (const InputError& e) {
    std::cerr << program << ": error: " << e.what() << "\n";
    return exit_code::kInputError;
  } catch (const std::exception& e) {
    std::cerr << program << ": internal error: " << e.what() << "\n";
    return exit_code::kInternal;
  }
  return exitCode;
}

}  // namespace invr::cli
