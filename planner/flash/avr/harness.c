/* One emulated driver MCU: simavr runs the firmware ELF on an ATmega328P at 16 MHz.
 *
 *   vlp-avr-harness FIRMWARE.elf EEPROM.bin TRACE.vcd|-
 *
 * USART0 is stdin (bytes to the MCU, paced by the UART's own receive FIFO) and stdout
 * (bytes the MCU sends). The EEPROM is the 1,024-byte file EEPROM.bin, mapped shared, so
 * every byte the firmware programs is in the file the moment it is written (a SIGKILL is a
 * power cut that loses nothing programmed). PB1, the LED pin, goes to a VCD trace (time in
 * ps). Simulated time is held to wall-clock time while the MCU sleeps. Exits at EOF on stdin
 * or on SIGTERM. Built by planner/flash/avr/build.py against Debian's libsimavr 1.6. */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <time.h>
#include <unistd.h>

#include "avr_eeprom.h"
#include "avr_ioport.h"
#include "avr_uart.h"
#include "sim_avr.h"
#include "sim_elf.h"
#include "sim_irq.h"

#define EEPROM_BYTES 1024
#define PS_PER_CYCLE 62500ULL /* 16 MHz */

static avr_t *avr;
static avr_irq_t *uart_in;
static int xoff;
static uint8_t in_buf[8192];
static size_t in_head, in_len;
static uint8_t out_buf[4096];
static size_t out_len;
static FILE *vcd;
static int led = -1;
static int stdin_open = 1;
static volatile sig_atomic_t stop;
static struct timespec t0;

static void fail(const char *what)
{
    fprintf(stderr, "vlp-avr-harness: %s: %s\n", what, strerror(errno));
    exit(1);
}

static void flush_out(void)
{
    size_t done = 0;
    while (done < out_len) {
        ssize_t n = write(1, out_buf + done, out_len - done);
        if (n < 0 && errno == EINTR) {
            continue;
        }
        if (n <= 0) {
            exit(0); /* nobody listens on the line any more */
        }
        done += (size_t)n;
    }
    out_len = 0;
}

static void on_uart_out(avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    (void)param;
    if (out_len == sizeof out_buf) {
        flush_out();
    }
    out_buf[out_len++] = (uint8_t)value;
}

static void feed_uart(void)
{
    while (!xoff && in_len) {
        uint8_t b = in_buf[in_head];
        in_head = (in_head + 1) % sizeof in_buf;
        in_len--;
        avr_raise_irq(uart_in, b);
    }
}

static void on_xon(avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    (void)value;
    (void)param;
    xoff = 0;
    feed_uart();
}

static void on_xoff(avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    (void)value;
    (void)param;
    xoff = 1;
}

static void on_led(avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    (void)param;
    if (vcd && (int)(value & 1) != led) {
        led = (int)(value & 1);
        fprintf(vcd, "#%llu\n%d!\n", (unsigned long long)avr->cycle * PS_PER_CYCLE, led);
    }
}

/* Read what stdin holds (non-blocking) into the input buffer and push it to the UART. */
static void service_io(void)
{
    flush_out();
    while (stdin_open && in_len < sizeof in_buf) {
        size_t tail = (in_head + in_len) % sizeof in_buf;
        size_t room = tail >= in_head ? sizeof in_buf - tail : in_head - tail;
        ssize_t n = read(0, in_buf + tail, room);
        if (n > 0) {
            in_len += (size_t)n;
        } else if (n == 0) {
            stdin_open = 0;
        } else {
            break; /* EAGAIN: nothing more now */
        }
    }
    feed_uart();
}

static uint64_t wall_ns(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (uint64_t)(t.tv_sec - t0.tv_sec) * 1000000000ULL + (uint64_t)t.tv_nsec - (uint64_t)t0.tv_nsec;
}

/* The MCU sleeps for `how_long` cycles: wait until wall-clock time catches up, waking for input. */
static void pace(avr_t *a, avr_cycle_count_t how_long)
{
    uint64_t due_ns = (uint64_t)(a->cycle + how_long) * PS_PER_CYCLE / 1000ULL, now = wall_ns();
    if (due_ns > now + 200000ULL) {
        struct pollfd fd = {0, POLLIN, 0};
        struct timespec wait = {(time_t)((due_ns - now) / 1000000000ULL), (long)((due_ns - now) % 1000000000ULL)};
        if (ppoll(&fd, stdin_open ? 1 : 0, &wait, NULL) > 0) {
            service_io();
        }
    }
}

/* simavr's own logger writes its chatter ("Loaded 8674 .text ...") to stdout, which is the line here:
 * errors go to stderr, the rest (traces, the UART's console copy) nowhere. */
static void log_to_stderr(avr_t *a, const int level, const char *format, va_list ap)
{
    (void)a;
    if (level == LOG_ERROR) {
        vfprintf(stderr, format, ap);
    }
}

static void on_signal(int signum)
{
    (void)signum;
    stop = 1;
}

int main(int argc, char **argv)
{
    elf_firmware_t fw;
    avr_io_t *io;
    uint8_t *eeprom;
    int fd;
    uint32_t uart_flags;
    avr_cycle_count_t next_service = 16000, next_flush = 0; /* input waits 1 ms: the USART is set up by then */

    if (argc != 4) {
        fprintf(stderr, "usage: vlp-avr-harness FIRMWARE.elf EEPROM.bin TRACE.vcd|-\n");
        return 2;
    }
    avr_global_logger_set(log_to_stderr);
    memset(&fw, 0, sizeof fw);
    if (elf_read_firmware(argv[1], &fw) != 0) {
        fprintf(stderr, "vlp-avr-harness: %s: not a readable AVR ELF file\n", argv[1]);
        return 1;
    }
    avr = avr_make_mcu_by_name("atmega328p");
    if (!avr) {
        fprintf(stderr, "vlp-avr-harness: simavr has no atmega328p\n");
        return 1;
    }
    avr_init(avr);
    avr->log = 0;
    avr->frequency = 16000000;
    avr_load_firmware(avr, &fw);
    avr->frequency = 16000000;

    fd = open(argv[2], O_RDWR);
    if (fd < 0) {
        fail(argv[2]);
    }
    if (lseek(fd, 0, SEEK_END) != EEPROM_BYTES) {
        fprintf(stderr, "vlp-avr-harness: %s: not a %d-byte EEPROM image\n", argv[2], EEPROM_BYTES);
        return 1;
    }
    eeprom = mmap(NULL, EEPROM_BYTES, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
    if (eeprom == MAP_FAILED) {
        fail(argv[2]);
    }
    for (io = avr->io_port; io; io = io->next) { /* write-through: the EEPROM's bytes are the file */
        if (io->kind && !strcmp(io->kind, "eeprom")) {
            avr_eeprom_t *ee = (avr_eeprom_t *)io;
            if (ee->size != EEPROM_BYTES) {
                fprintf(stderr, "vlp-avr-harness: EEPROM of %u bytes, expected %d\n", ee->size, EEPROM_BYTES);
                return 1;
            }
            free(ee->eeprom);
            ee->eeprom = eeprom;
        }
    }

    if (strcmp(argv[3], "-") != 0) {
        vcd = fopen(argv[3], "w");
        if (!vcd) {
            fail(argv[3]);
        }
        fprintf(vcd, "$timescale 1ps $end\n$scope module driver $end\n$var wire 1 ! led $end\n$upscope $end\n"
                     "$enddefinitions $end\n");
        avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('B'), 1), on_led, NULL);
    }
    uart_flags = 0; /* no copy of the line on the console, no host sleep while the firmware polls UDRE */
    avr_ioctl(avr, AVR_IOCTL_UART_SET_FLAGS('0'), &uart_flags);
    uart_in = avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT), on_uart_out, NULL);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XON), on_xon, NULL);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XOFF), on_xoff, NULL);
    avr->sleep = pace;
    fcntl(0, F_SETFL, fcntl(0, F_GETFL) | O_NONBLOCK);
    signal(SIGTERM, on_signal);
    signal(SIGINT, on_signal);
    signal(SIGPIPE, SIG_IGN);
    clock_gettime(CLOCK_MONOTONIC, &t0);

    while (!stop && (stdin_open || in_len)) {
        int state = avr_run(avr);
        if (state == cpu_Done || state == cpu_Crashed) {
            fprintf(stderr, "vlp-avr-harness: the MCU stopped (state %d)\n", state);
            break;
        }
        if (avr->cycle >= next_service) {
            service_io();
            next_service = avr->cycle + 1600; /* every 100 us of MCU time */
            if (vcd && avr->cycle >= next_flush) {
                fflush(vcd);
                next_flush = avr->cycle + 1600000; /* every 100 ms */
            }
        }
    }
    flush_out();
    if (vcd) {
        fclose(vcd);
    }
    return 0;
}
