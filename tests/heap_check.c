/* A Windows library for the tests: a host loads it before the FMUs' libraries, so that Windows detaches it after
 * them when the process exits; then it validates every heap of the process and prints "heaps N corrupted K" on the
 * standard output. A write into a freed block during the exit (the FMI libraries' Python start-up object destroyed
 * a second time) makes K > 0 where the process runs with the heap's free checking on (Image File Execution Options'
 * GlobalFlag FLG_HEAP_ENABLE_FREE_CHECK, 0x20), which fills freed blocks with a pattern that validation checks.
 * Build: x86_64-w64-mingw32-gcc -shared -o heap_check.dll heap_check.c */
#define WIN32_LEAN_AND_MEAN
#include <windows.h>
#include <stdio.h>

BOOL WINAPI DllMain(HINSTANCE self, DWORD reason, LPVOID process_exit)
{
    (void)self;
    if (reason != DLL_PROCESS_DETACH || !process_exit) return TRUE;
    HANDLE heaps[256];
    DWORD n = GetProcessHeaps(sizeof heaps / sizeof *heaps, heaps), corrupted = 0, written;
    for (DWORD i = 0; i < n && i < sizeof heaps / sizeof *heaps; ++i)
        if (!HeapValidate(heaps[i], 0, NULL)) ++corrupted;
    char line[64];
    int length = snprintf(line, sizeof line, "heaps %lu corrupted %lu\n", (unsigned long)n, (unsigned long)corrupted);
    WriteFile(GetStdHandle(STD_OUTPUT_HANDLE), line, (DWORD)length, &written, NULL);
    return TRUE;
}
