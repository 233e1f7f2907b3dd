#include "pipeline/core/guarded.h"

#include <exception>

#include "pipeline/core/error.h"
#include "pipeline/core/log.h"

namespace fourd {

int run_guarded(std::string_view tool, const std::function<int()>& body) {
  try {
    return body();
  } catch (const Error& e) {
    log::error("{}: {}", tool, e.what());
    return e.exit_code();
  } catch (const std::exception& e) {
    log::error("{}: internal error: {}", tool, e.what());
    return kExitFailure;
  }
}

}  // namespace fourd
