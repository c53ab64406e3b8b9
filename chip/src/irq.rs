//! The interrupt lines into each core's NVIC (datasheet 2.3.2, table "Interrupts"): IRQ n
//! is the core's external interrupt n (exception 16 + n). Both cores see all 26 lines.

/// TIMER_IRQ_0 (alarm n raises `TIMER_IRQ_0 + n`, n < 4; datasheet 4.6).
pub const TIMER_IRQ_0: u32 = 0;
/// PWM_IRQ_WRAP.
pub const PWM_IRQ_WRAP: u32 = 4;
/// USBCTRL_IRQ.
pub const USBCTRL_IRQ: u32 = 5;
/// XIP_IRQ.
pub const XIP_IRQ: u32 = 6;
/// PIO0_IRQ_0 (PIO0_IRQ_1 is 8, PIO1_IRQ_0 9, PIO1_IRQ_1 10).
pub const PIO0_IRQ_0: u32 = 7;
/// DMA_IRQ_0.
pub const DMA_IRQ_0: u32 = 11;
/// DMA_IRQ_1.
pub const DMA_IRQ_1: u32 = 12;
/// IO_IRQ_BANK0.
pub const IO_IRQ_BANK0: u32 = 13;
/// IO_IRQ_QSPI.
pub const IO_IRQ_QSPI: u32 = 14;
/// SIO_IRQ_PROC0: core 0's inter-core FIFO (datasheet 2.3.1.4).
pub const SIO_IRQ_PROC0: u32 = 15;
/// SIO_IRQ_PROC1: core 1's inter-core FIFO.
pub const SIO_IRQ_PROC1: u32 = 16;
/// CLOCKS_IRQ.
pub const CLOCKS_IRQ: u32 = 17;
/// SPI0_IRQ (SPI1_IRQ is 19).
pub const SPI0_IRQ: u32 = 18;
/// UART0_IRQ (UART1_IRQ is 21).
pub const UART0_IRQ: u32 = 20;
/// ADC_IRQ_FIFO.
pub const ADC_IRQ_FIFO: u32 = 22;
/// I2C0_IRQ (I2C1_IRQ is 24).
pub const I2C0_IRQ: u32 = 23;
/// RTC_IRQ.
pub const RTC_IRQ: u32 = 25;
/// Number of interrupt lines.
pub const LINES: u32 = 26;
