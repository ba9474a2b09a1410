// The source of the target whose precompiled header every test binary
// reuses (tests/CMakeLists.txt): it compiles the header and nothing else.
