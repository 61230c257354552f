/* A stand-in for Windows' bcryptprimitives.dll, for the wine tests only:
 * Rust's standard library on Windows 10 and later draws its random numbers
 * from bcryptprimitives.dll!ProcessPrng, which Debian's wine 8.0 lacks.
 * This one answers from RtlGenRandom (advapi32's SystemFunction036), which
 * wine has. It is placed beside the test importer, never in an FMU. */

#include <windows.h>

BOOLEAN WINAPI SystemFunction036(PVOID buffer, ULONG length);

__declspec(dllexport) BOOL WINAPI ProcessPrng(PBYTE data, SIZE_T length) {
    while (length > 0) {
        ULONG chunk = length > 0x10000000 ? 0x10000000 : (ULONG)length;
        if (!SystemFunction036(data, chunk)) return FALSE;
        data += chunk;
        length -= chunk;
    }
    return TRUE;
}
