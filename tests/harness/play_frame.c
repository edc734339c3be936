/* Host harness for a generated vlp_config.h (tests/firmware/test_firmware.py builds it with
 * gcc -std=c99 -pedantic -Wall -Wextra -Werror -I <luminaire folder>).
 * Prints the header's numbers, two frame periods of chips via vlp_chip(), and the
 * name and line code strings, so the test can compare them with Python's. */
#include <stdio.h>
#include "vlp_config.h"

int main(void)
{
    unsigned long i;

    printf("id %lu\n", (unsigned long)VLP_ID);
    printf("chips %lu\n", (unsigned long)VLP_CHIP_COUNT);
    printf("reload %lu\n", (unsigned long)VLP_TIMER_RELOAD);
    printf("ticks %lu\n", (unsigned long)VLP_TIMER_TICKS);
    printf("millihz %lu\n", (unsigned long)VLP_CHIP_RATE_MILLIHZ);
    printf("rate %.6f\n", (double)VLP_CHIP_RATE_HZ);
    printf("frame ");
    for (i = 0; i < 2UL * VLP_CHIP_COUNT; ++i) {
        putchar('0' + vlp_chip((uint16_t)(i % VLP_CHIP_COUNT)));
    }
    printf("\nline_code %s\nplan %s\nname %s\n", VLP_LINE_CODE, VLP_PLAN_HASH, VLP_LUMINAIRE_NAME);
    return 0;
}
