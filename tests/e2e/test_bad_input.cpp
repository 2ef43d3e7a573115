// placeholder, written by the bad-input test author
#include <gtest/gtest.h>
