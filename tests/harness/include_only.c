/* Includes the generated header and uses nothing from it: with -Wall -Wextra -Werror
 * this fails if the header defines anything that warns when unused. */
#include "vlp_config.h"

int main(void)
{
    return 0;
}
