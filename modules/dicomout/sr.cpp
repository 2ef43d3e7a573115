#include "dicomout/common.h"

namespace ms::dicomout {}  // namespace ms::dicomout
