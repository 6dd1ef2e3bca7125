// Shared main for every CppUTest binary. Leak detection through CppUTest's new/delete overloads is
// off: it reports false leaks for standard-library statics and library threads (Paho, SQLite).
// The `debug` preset runs the same tests under AddressSanitizer, which finds real leaks.
#include <CppUTest/CommandLineTestRunner.h>
#include <CppUTest/MemoryLeakWarningPlugin.h>

int main(int argc, char** argv) {
  MemoryLeakWarningPlugin::turnOffNewDeleteOverloads();
  return CommandLineTestRunner::RunAllTests(argc, argv);
}
