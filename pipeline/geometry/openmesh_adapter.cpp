#include "pipeline/geometry/openmesh_adapter.h"

#include <OpenMesh/Core/System/omstream.hh>

namespace fourd {

void silence_openmesh() {
  static const bool done = [] {
    omerr().disable();
    omlog().disable();
    return true;
  }();
  (void)done;
}

}  // namespace fourd
