/* libc_small.c - memcpy, memset and memcmp for both images: byte loops of a few bytes
 * each in place of newlib-nano's (about 490 B, a twelfth of the bootloader's 6 KiB target
 * and more than the application can spare under its 16 KiB goal). Speed hardly matters:
 * the copies are of frames and register blocks (tens of bytes) and the 1.5 KiB RAM image
 * at reset. Built with -fno-tree-loop-distribute-patterns so GCC does not turn the loops
 * back into calls. */
#include <string.h>

void *memcpy(void *restrict dst, const void *restrict src, size_t n)
{
    unsigned char *d = dst;
    const unsigned char *s = src;
    while (n--)
        *d++ = *s++;
    return dst;
}

void *memset(void *dst, int c, size_t n)
{
    unsigned char *d = dst;
    while (n--)
        *d++ = (unsigned char)c;
    return dst;
}

int memcmp(const void *a, const void *b, size_t n)
{
    const unsigned char *p = a, *q = b;
    for (; n; n--, p++, q++)
        if (*p != *q)
            return *p - *q;
    return 0;
}
