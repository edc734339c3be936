/* The reference driver's hardware side: USART receive into a ring, the idle loop (sleeps:
 * simavr 1.6 takes an interrupt one instruction late after sei), and the modulator, which
 * drives the LED pin from the Timer1 compare interrupt (CTC, prescaler 1): one chip per
 * `ticks` cycles, the next chip's level prepared so the pin changes at a fixed latency. */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>
#include <string.h>
#include "driver.h"

#define LED_DDR DDRB
#define LED_PORT PORTB
#define LED_BIT PB1 /* Arduino pin 9 */
#define FRAME_MAX 192u /* the longest request this driver takes: a WRITE of VLP_MAX_BLOCK, COBS-encoded */

static volatile uint8_t rx_ring[256];
static volatile uint8_t rx_head, rx_tail;

static uint8_t chip_bytes[IMG_MAX_CHIPS / 8u];
static volatile uint16_t chip_count, chip_index;
static volatile uint8_t next_on;

ISR(USART_RX_vect)
{
    uint8_t b = UDR0, head = rx_head;
    if ((uint8_t)(head + 1u) != rx_tail) { /* full: the byte is lost, the frame's CRC fails */
        rx_ring[head] = b;
        rx_head = (uint8_t)(head + 1u);
    }
}

ISR(TIMER1_COMPA_vect)
{
    uint16_t i;
    if (next_on) {
        LED_PORT |= _BV(LED_BIT);
    } else {
        LED_PORT &= (uint8_t)~_BV(LED_BIT);
    }
    i = chip_index + 1u;
    if (i >= chip_count) {
        i = 0;
    }
    chip_index = i;
    next_on = (uint8_t)((chip_bytes[i >> 3] >> (7u - (i & 7u))) & 1u);
}

void modulator_play(const uint8_t *chips, uint16_t count, uint32_t ticks)
{
    cli();
    TCCR1B = 0;
    TIMSK1 = 0;
    LED_DDR |= _BV(LED_BIT);
    if (count == 0 || ticks < 2 || ticks > 65536UL) {
        LED_PORT |= _BV(LED_BIT); /* no configuration: steady light */
        chip_count = 0;
    } else {
        memcpy(chip_bytes, chips, (count + 7u) / 8u);
        chip_count = count;
        chip_index = 0;
        next_on = (uint8_t)(chip_bytes[0] >> 7);
        TCNT1 = 0;
        OCR1A = (uint16_t)(ticks - 1u);
        TCCR1A = 0;
        TIFR1 = _BV(OCF1A);
        TIMSK1 = _BV(OCIE1A);
        TCCR1B = _BV(WGM12) | _BV(CS10);
    }
    sei();
}

void uart_send(const uint8_t *p, uint16_t n)
{
    while (n--) {
        loop_until_bit_is_set(UCSR0A, UDRE0);
        UDR0 = *p++;
    }
}

int main(void)
{
    static uint8_t frame[FRAME_MAX];
    uint16_t length = 0;
    uint8_t overrun = 0;

    UBRR0 = (uint16_t)(VLP_CPU_HZ / (16UL * VLP_BAUD) - 1u);
    UCSR0A = 0;
    UCSR0C = _BV(UCSZ01) | _BV(UCSZ00); /* 8N1 */
    UCSR0B = _BV(RXEN0) | _BV(TXEN0) | _BV(RXCIE0);
    set_sleep_mode(SLEEP_MODE_IDLE);
    sei(); /* requests arriving while the slots are hashed wait in the ring */
    driver_boot(); /* reads the EEPROM, starts the modulator */
    for (;;) {
        uint8_t b;
        cli();
        if (rx_head == rx_tail) {
            sleep_enable();
            sei();
            sleep_cpu();
            sleep_disable();
            continue;
        }
        sei();
        b = rx_ring[rx_tail];
        rx_tail = (uint8_t)(rx_tail + 1u);
        if (b == 0) {
            if (length && !overrun) {
                driver_frame(frame, length);
            }
            length = 0;
            overrun = 0;
        } else if (length < FRAME_MAX) {
            frame[length++] = b;
        } else {
            overrun = 1; /* longer than any request we take: dropped up to the next delimiter */
        }
    }
}
