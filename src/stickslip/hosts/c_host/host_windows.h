/* The few POSIX calls the C hosts make that Windows lacks, for their Windows build (MinGW-w64, winpthreads):
 * dlopen, dlsym, dlclose and dlerror over LoadLibraryW and GetProcAddress, with UTF-8 paths, and the command line
 * as UTF-8 (Windows hands main its arguments in the ANSI code page, which cannot hold every folder's name). */
#ifndef SBF_HOST_WINDOWS_H
#define SBF_HOST_WINDOWS_H
#define WIN32_LEAN_AND_MEAN
#include <windows.h>
#include <psapi.h>
#include <shellapi.h>
#include <stdio.h>
#include <stdlib.h>

#define RTLD_NOW 2
#define RTLD_LOCAL 0
static char host_dl_error[512];

static void *dlopen(const char *path, int flags)
{
    (void)flags;
    wchar_t wide[32768];
    HMODULE library = NULL;
    if (MultiByteToWideChar(CP_UTF8, 0, path, -1, wide, 32768) > 0)
        library = LoadLibraryExW(wide, NULL, LOAD_WITH_ALTERED_SEARCH_PATH);
    if (!library) snprintf(host_dl_error, sizeof host_dl_error, "%s: Windows error %lu", path, GetLastError());
    return library;
}

static void *dlsym(void *library, const char *name) { return (void *)GetProcAddress((HMODULE)library, name); }

static int dlclose(void *library) { return FreeLibrary((HMODULE)library) ? 0 : -1; }

static const char *dlerror(void) { return host_dl_error; }

/* The process's working set in kB, or -1 */
static long resident_kb(void)
{
    PROCESS_MEMORY_COUNTERS counters;
    if (!K32GetProcessMemoryInfo(GetCurrentProcess(), &counters, sizeof counters)) return -1;
    return (long)(counters.WorkingSetSize / 1024);
}

/* argv as UTF-8 (from the UTF-16 command line); exits with 2 if it cannot be had */
static char **utf8_arguments(int argc)
{
    int n = 0;
    wchar_t **wide = CommandLineToArgvW(GetCommandLineW(), &n);
    char **utf8 = calloc((size_t)argc + 1, sizeof *utf8);
    if (!wide || !utf8 || n != argc) exit(2);
    for (int i = 0; i < n; ++i) {
        int size = WideCharToMultiByte(CP_UTF8, 0, wide[i], -1, NULL, 0, NULL, NULL);
        if (size <= 0 || !(utf8[i] = malloc((size_t)size))) exit(2);
        WideCharToMultiByte(CP_UTF8, 0, wide[i], -1, utf8[i], size, NULL, NULL);
    }
    LocalFree(wide);
    return utf8;
}
#endif
