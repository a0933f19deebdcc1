// doctest entry point shared by every test executable.
#define DOCTEST_CONFIG_IMPLEMENT
#include <doctest/doctest.h>

#include <cstring>
#include <iostream>

#include "support.h"

namespace {

/// The number of test cases the last run selected. ctest runs each case on its own
/// (doctest_discover_tests: --test-case=NAME), and a name the filter cannot match, such as one cut
/// at a ';' (CMake's list separator), would otherwise pass having run nothing.
unsigned g_selected = 0;

struct SelectedCount : doctest::IReporter {
    explicit SelectedCount(const doctest::ContextOptions&) {}
    void report_query(const doctest::QueryData&) override {}
    void test_run_start() override {}
    void test_run_end(const doctest::TestRunStats& stats) override {
        g_selected = stats.numTestCasesPassingFilters;
    }
    void test_case_start(const doctest::TestCaseData&) override {}
    void test_case_reenter(const doctest::TestCaseData&) override {}
    void test_case_end(const doctest::CurrentTestCaseStats&) override {}
    void test_case_exception(const doctest::TestCaseException&) override {}
    void subcase_start(const doctest::SubcaseSignature&) override {}
    void subcase_end() override {}
    void log_assert(const doctest::AssertData&) override {}
    void log_message(const doctest::MessageData&) override {}
    void test_case_skipped(const doctest::TestCaseData&) override {}
};
REGISTER_LISTENER("selected-count", 1, SelectedCount);

/// Whether argv[i] starts with one of doctest's spellings of option `name` (--name, -name,
/// --dt-name, -dt-name; `abbrev` is its short form, such as "tc").
bool has_option(int argc, char** argv, const char* name, const char* abbrev) {
    for (int i = 1; i < argc; ++i) {
        const char* a = argv[i];
        while (*a == '-')
            ++a;
        if (std::strncmp(a, "dt-", 3) == 0) a += 3;
        for (const char* n : {name, abbrev}) {
            const std::size_t len = std::strlen(n);
            if (std::strncmp(a, n, len) == 0 && (a[len] == '=' || a[len] == '\0')) return true;
        }
    }
    return false;
}

/// Whether the command line names test cases to run, and runs them.
bool filters_test_cases(int argc, char** argv) {
    return has_option(argc, argv, "test-case", "tc") && !has_option(argc, argv, "no-run", "nr");
}

} // namespace

int main(int argc, char** argv) {
    doctest::Context context(argc, argv);
    const int code = context.run();
    tandem::test::release_device_context(); // before exit: see release_device_context
    if (code == 0 && !context.shouldExit() && filters_test_cases(argc, argv) && g_selected == 0) {
        std::cerr << "error: no test case matches the --test-case filter (a name with ';' or an "
                     "unescaped ',' cannot be matched)\n";
        return 1;
    }
    return code;
}
