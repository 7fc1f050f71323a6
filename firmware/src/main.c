/* dualrgb LED sphere, reference firmware 1.1.0 for the ATmega2560 (Arduino Mega 2560): the protocol of
 * docs/led-sphere-protocol.md on USART0, 10 PWM outputs, and the sphere's own safety (sphere.c).
 *
 * Dark from the first instruction: at reset every pin is an input and the board's pull-downs hold the LED
 * switches off; .init3 (before the C runtime) makes the PWM pins outputs driven low and arms the chip's watchdog.
 * The fuses below enable the brown-out detector (2.7 V: below it the chip is held in reset, so dark) and keep
 * the watchdog always on (WDTON). */
#include <string.h>
#include <avr/eeprom.h>
#include <avr/fuse.h>
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>
#include <avr/wdt.h>
#include "board.h"
#include "inputs.h"
#include "outputs.h"
#include "protocol.h"
#include "serial.h"
#include "sphere.h"

/* low 0xFF: external crystal 16 MHz, slow start-up; high 0xC1: SPI programming on, JTAG off, WDTON (the watchdog
 * cannot be switched off), EESAVE (the serial number survives a chip erase), no boot loader (reset at 0x0000);
 * extended 0xFD: BODLEVEL 2.7 V. firmware/README.md: how to write them (avrdude) and the boot-loader route. */
FUSES = {
    .low = 0xFF,
    .high = 0xC1,
    .extended = 0xFD,
};

#define SERIAL_BYTES 16
EEMEM char ee_serial[SERIAL_BYTES] = SPHERE_SERIAL;

uint8_t reset_cause __attribute__((section(".noinit")));

/* Runs before .data and .bss are set up: note why the chip reset, clear the flags (a watchdog reset must not
 * leave WDRF set, or the watchdog stays armed at 16 ms), arm the watchdog, drive the PWM pins low. */
void early_init(void) __attribute__((naked, used, section(".init3")));
void early_init(void)
{
    reset_cause = MCUSR;
    MCUSR = 0;
    wdt_enable(WDTO_250MS);
    PORTB &= (uint8_t)~(_BV(PB5) | _BV(PB6));
    DDRB |= _BV(PB5) | _BV(PB6);
    PORTE &= (uint8_t)~(_BV(PE3) | _BV(PE4) | _BV(PE5));
    DDRE |= _BV(PE3) | _BV(PE4) | _BV(PE5);
    PORTH &= (uint8_t)~(_BV(PH3) | _BV(PH4) | _BV(PH5));
    DDRH |= _BV(PH3) | _BV(PH4) | _BV(PH5);
    PORTL &= (uint8_t)~(_BV(PL3) | _BV(PL4));
    DDRL |= _BV(PL3) | _BV(PL4);
}

/* A reset other than power-on (brown-out, the chip's watchdog, the reset pin, JTAG) may have ended a lit period
 * the host did not end: say so as the sphere says it of its own switch-offs, trip=1. After a power-on reset
 * there was no lit period this chip could have known about. */
static uint8_t tripped_by_reset(uint8_t cause)
{
    if (cause & _BV(PORF))
        return 0;
    return (cause & (_BV(BORF) | _BV(WDRF) | _BV(EXTRF) | _BV(JTRF))) != 0;
}

/* The EEPROM's serial number if it is 1..15 printable characters without spaces, else SN-UNSET. */
static void read_serial(char *serial)
{
    eeprom_read_block(serial, ee_serial, SERIAL_BYTES);
    uint8_t n = 0;
    while (n < SERIAL_BYTES && serial[n] > ' ' && serial[n] <= '~')
        n++;
    if (n == 0 || n == SERIAL_BYTES || serial[n] != '\0')
        strcpy(serial, "SN-UNSET");
}

int main(void)
{
    static char serial[SERIAL_BYTES];
    outputs_init();
    inputs_init();
    read_serial(serial);
    protocol_init(serial);
    serial_init();
    sphere_init(tripped_by_reset(reset_cause), inputs_first_temperature());
    set_sleep_mode(SLEEP_MODE_IDLE);        /* timers, UART and ADC keep running */
    sei();
    for (;;) {
        wdt_reset();
        uint8_t waiting = protocol_poll();
        cli();
        if (!serial_available() || waiting) {
            sleep_enable();
            sei();
            sleep_cpu();                    /* the next byte or tick wakes it */
            sleep_disable();
        }
        sei();
    }
}
