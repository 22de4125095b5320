// PLACEHOLDER: being written.
#include <cstdio>
#include "aos/util/version.h"
int main() { std::printf("aos-render %s\n", aos::kVersion); return 0; }
