//! The WeAct STM32F411CEU6 "Black Pill" as this firmware uses it: the clock tree, the interrupt
//! bindings, and which peripheral or pin each part of the firmware gets.

use embassy_stm32::gpio::{Level, Output, Speed};
use embassy_stm32::peripherals::{
    ADC1, DMA1_CH0, DMA1_CH6, FLASH, I2C1, IWDG, PA11, PA12, PB6, PB7, USB_OTG_FS,
};
use embassy_stm32::time::Hertz;
use embassy_stm32::{bind_interrupts, dma, flash, i2c, peripherals, usb, Config, Peri};

/// The crystal on the Black Pill.
const HSE_FREQUENCY_HZ: u32 = 25_000_000;

bind_interrupts!(
    /// Every interrupt the firmware uses, bound to its embassy handler.
    pub struct Irqs {
        OTG_FS => usb::InterruptHandler<USB_OTG_FS>;
        I2C1_EV => i2c::EventInterruptHandler<peripherals::I2C1>;
        I2C1_ER => i2c::ErrorInterruptHandler<peripherals::I2C1>;
        // RM0383 DMA1 request map: I2C1_RX on stream 0 or 5, I2C1_TX on stream 6, 7 or 1.
        DMA1_STREAM0 => dma::InterruptHandler<peripherals::DMA1_CH0>;
        DMA1_STREAM6 => dma::InterruptHandler<peripherals::DMA1_CH6>;
        FLASH => flash::InterruptHandler;
    }
);

/// USB OTG FS and its data pins.
pub struct UsbPeripherals {
    /// The USB OTG full-speed core.
    pub otg_fs: Peri<'static, USB_OTG_FS>,
    /// D+ (PA12).
    pub d_plus: Peri<'static, PA12>,
    /// D- (PA11).
    pub d_minus: Peri<'static, PA11>,
}

/// I2C1, its pins and its DMA streams: the sensor bus (FDC1004 and TMP117).
pub struct I2cPeripherals {
    /// The I2C1 controller.
    pub i2c1: Peri<'static, I2C1>,
    /// SCL (PB6).
    pub scl: Peri<'static, PB6>,
    /// SDA (PB7).
    pub sda: Peri<'static, PB7>,
    /// DMA1 stream 6, I2C1_TX.
    pub tx_dma: Peri<'static, DMA1_CH6>,
    /// DMA1 stream 0, I2C1_RX.
    pub rx_dma: Peri<'static, DMA1_CH0>,
}

/// The board after clock setup, split by user.
pub struct Board {
    /// The USB port.
    pub usb: UsbPeripherals,
    /// The sensor bus.
    pub i2c: I2cPeripherals,
    /// The flash controller (calibration storage).
    pub flash: Peri<'static, FLASH>,
    /// ADC1 (die temperature sensor).
    pub adc: Peri<'static, ADC1>,
    /// The independent watchdog.
    pub iwdg: Peri<'static, IWDG>,
    /// The blue LED on PC13, off.
    pub led: Output<'static>,
}

/// Configures the clocks and hands out the peripherals.
pub fn init() -> Board {
    let p = embassy_stm32::init(clock_config());
    Board {
        usb: UsbPeripherals {
            otg_fs: p.USB_OTG_FS,
            d_plus: p.PA12,
            d_minus: p.PA11,
        },
        i2c: I2cPeripherals {
            i2c1: p.I2C1,
            scl: p.PB6,
            sda: p.PB7,
            tx_dma: p.DMA1_CH6,
            rx_dma: p.DMA1_CH0,
        },
        flash: p.FLASH,
        adc: p.ADC1,
        iwdg: p.IWDG,
        // The LED hangs between 3V3 and PC13: active low, and PC13 may only sink 3 mA at low speed.
        led: Output::new(p.PC13, Level::High, Speed::Low),
    }
}

fn clock_config() -> Config {
    use embassy_stm32::rcc::{
        mux, AHBPrescaler, APBPrescaler, Hse, HseMode, Pll, PllMul, PllPDiv, PllPreDiv, PllQDiv,
        PllSource, Sysclk,
    };

    let mut config = Config::default();
    config.rcc.hse = Some(Hse {
        freq: Hertz(HSE_FREQUENCY_HZ),
        mode: HseMode::Oscillator,
    });
    config.rcc.pll_src = PllSource::HSE;
    // 25 MHz / M=25 = 1 MHz PLL input (1..2 MHz allowed; 2 MHz would need M=12.5).
    // VCO = 1 MHz * N=192 = 192 MHz (100..432 MHz allowed).
    // SYSCLK = 192 / P=2 = 96 MHz; USB = 192 / Q=4 = 48 MHz exactly.
    // 100 MHz is not possible with an exact 48 MHz: the VCO must be a multiple of 48 MHz (Q is an
    // integer) and equal 100 MHz * P with P in {2, 4, 6, 8}; 200 and 400 MHz are not multiples of
    // 48, 600 and 800 MHz exceed the VCO range. embassy-stm32 panics if USB is off by > 0.25 %.
    config.rcc.pll = Some(Pll {
        prediv: PllPreDiv::DIV25,
        mul: PllMul::MUL192,
        divp: Some(PllPDiv::DIV2),
        divq: Some(PllQDiv::DIV4),
        divr: None,
    });
    config.rcc.sys = Sysclk::PLL1_P;
    config.rcc.ahb_pre = AHBPrescaler::DIV1;
    // APB1 is limited to 50 MHz on the F411; its timers (the TIM2 time driver) still run at 96 MHz.
    config.rcc.apb1_pre = APBPrescaler::DIV2;
    config.rcc.apb2_pre = APBPrescaler::DIV1;
    config.rcc.mux.clk48sel = mux::Clk48sel::PLL1_Q;
    config
}
