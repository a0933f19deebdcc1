// doctest entry point shared by every test executable.
#define DOCTEST_CONFIG_IMPLEMENT
#include <doctest/doctest.h>

#include "support.h"

int main(int argc, char** argv) {
    doctest::Context context(argc, argv);
    const int code = context.run();
    tandem::test::release_device_context(); // before exit: see release_device_context
    return code;
}
