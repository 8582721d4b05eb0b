/* STM32F10x register map: the addresses and bits this firmware uses, nothing more.
 * Written from the reference manual (RM0008) and the Cortex-M3 architecture manual;
 * no vendor headers. Names follow the manual (register_BIT) with a HAL_ prefix. */
#ifndef SNAKEBOT_HAL_REGS_H
#define SNAKEBOT_HAL_REGS_H

#define HAL_BIT(n) (1UL << (n))

/* ---- Cortex-M3 system control space ---- */
#define HAL_SYST_CSR            0xE000E010UL  /* SysTick control and status */
#define HAL_SYST_RVR            0xE000E014UL  /* reload value (24 bits) */
#define HAL_SYST_CVR            0xE000E018UL  /* current value */
#define HAL_SYST_CSR_ENABLE     HAL_BIT(0)
#define HAL_SYST_CSR_TICKINT    HAL_BIT(1)
#define HAL_SYST_CSR_CLKSOURCE  HAL_BIT(2)    /* 1 = processor clock (HCLK) */
#define HAL_SYST_RVR_MAX        0x00FFFFFFUL

#define HAL_NVIC_ISER(n)        (0xE000E100UL + 4UL * (n))  /* set-enable, 32 IRQs per word */
#define HAL_NVIC_ICER(n)        (0xE000E180UL + 4UL * (n))  /* clear-enable */
#define HAL_NVIC_ICPR(n)        (0xE000E280UL + 4UL * (n))  /* clear-pending */
#define HAL_NVIC_IPR_BASE       0xE000E400UL                /* one priority byte per IRQ */

#define HAL_SCB_ICSR            0xE000ED04UL  /* interrupt control and state */
#define HAL_SCB_ICSR_PENDSTCLR  HAL_BIT(25)   /* write 1: clear a pending SysTick */
#define HAL_SCB_ICSR_PENDSVCLR  HAL_BIT(27)   /* write 1: clear a pending PendSV */
#define HAL_SCB_VTOR            0xE000ED08UL  /* vector table offset */
#define HAL_SCB_AIRCR           0xE000ED0CUL
#define HAL_SCB_AIRCR_KEY       0x05FA0000UL
#define HAL_SCB_AIRCR_SYSRESETREQ HAL_BIT(2)
#define HAL_SCB_SHPR3           0xE000ED20UL  /* priorities of PendSV (bits 23:16) and SysTick (31:24) */

/* STM32F1 implements the top 4 priority bits. */
#define HAL_NVIC_PRIO_BITS      4

/* ---- Interrupt numbers (position in the vector table after the 16 system entries) ---- */
#define HAL_IRQ_USART1          37
#define HAL_IRQ_USART2          38
#define HAL_IRQ_USART3          39
#define HAL_IRQ_UART4           52
#define HAL_IRQ_UART5           53
#define HAL_IRQ_COUNT           60            /* STM32F103 high density */

/* ---- Peripheral base addresses ---- */
#define HAL_IWDG_BASE           0x40003000UL
#define HAL_USART2_BASE         0x40004400UL
#define HAL_USART3_BASE         0x40004800UL
#define HAL_UART4_BASE          0x40004C00UL
#define HAL_UART5_BASE          0x40005000UL
#define HAL_AFIO_BASE           0x40010000UL
#define HAL_GPIOA_BASE          0x40010800UL
#define HAL_GPIOB_BASE          0x40010C00UL
#define HAL_GPIOC_BASE          0x40011000UL
#define HAL_GPIOD_BASE          0x40011400UL
#define HAL_USART1_BASE         0x40013800UL
#define HAL_RCC_BASE            0x40021000UL
#define HAL_FLASH_R_BASE        0x40022000UL  /* flash interface registers (FPEC) */

/* ---- RCC ---- */
#define HAL_RCC_CR              (HAL_RCC_BASE + 0x00UL)
#define HAL_RCC_CFGR            (HAL_RCC_BASE + 0x04UL)
#define HAL_RCC_CIR             (HAL_RCC_BASE + 0x08UL)
#define HAL_RCC_APB2ENR         (HAL_RCC_BASE + 0x18UL)
#define HAL_RCC_APB1ENR         (HAL_RCC_BASE + 0x1CUL)
#define HAL_RCC_CSR             (HAL_RCC_BASE + 0x24UL)

#define HAL_RCC_CR_HSION        HAL_BIT(0)
#define HAL_RCC_CR_HSIRDY       HAL_BIT(1)
#define HAL_RCC_CR_HSEON        HAL_BIT(16)
#define HAL_RCC_CR_HSERDY       HAL_BIT(17)
#define HAL_RCC_CR_HSEBYP       HAL_BIT(18)
#define HAL_RCC_CR_PLLON        HAL_BIT(24)
#define HAL_RCC_CR_PLLRDY       HAL_BIT(25)

#define HAL_RCC_CFGR_SW_MASK    (3UL << 0)
#define HAL_RCC_CFGR_SW_HSI     (0UL << 0)
#define HAL_RCC_CFGR_SW_PLL     (2UL << 0)
#define HAL_RCC_CFGR_SWS_MASK   (3UL << 2)
#define HAL_RCC_CFGR_SWS_HSI    (0UL << 2)
#define HAL_RCC_CFGR_SWS_PLL    (2UL << 2)
#define HAL_RCC_CFGR_HPRE_MASK  (0xFUL << 4)   /* 0xxx = AHB /1 */
#define HAL_RCC_CFGR_PPRE1_MASK (7UL << 8)
#define HAL_RCC_CFGR_PPRE1_DIV2 (4UL << 8)
#define HAL_RCC_CFGR_PPRE2_MASK (7UL << 11)    /* 0xx = APB2 /1 */
#define HAL_RCC_CFGR_PLLSRC_HSE HAL_BIT(16)    /* 0 = HSI / 2 */
#define HAL_RCC_CFGR_PLLXTPRE   HAL_BIT(17)    /* 1 = HSE / 2 into the PLL */
#define HAL_RCC_CFGR_PLLMUL_MASK (0xFUL << 18)
#define HAL_RCC_CFGR_PLLMUL(x)  ((uint32_t)((x) - 2U) << 18)  /* x2 .. x16 */
#define HAL_RCC_CFGR_USBPRE     HAL_BIT(22)

#define HAL_RCC_APB2ENR_AFIOEN   HAL_BIT(0)
#define HAL_RCC_APB2ENR_IOPAEN   HAL_BIT(2)
#define HAL_RCC_APB2ENR_IOPBEN   HAL_BIT(3)
#define HAL_RCC_APB2ENR_IOPCEN   HAL_BIT(4)
#define HAL_RCC_APB2ENR_IOPDEN   HAL_BIT(5)
#define HAL_RCC_APB2ENR_USART1EN HAL_BIT(14)
#define HAL_RCC_APB1ENR_USART2EN HAL_BIT(17)
#define HAL_RCC_APB1ENR_USART3EN HAL_BIT(18)
#define HAL_RCC_APB1ENR_UART4EN  HAL_BIT(19)
#define HAL_RCC_APB1ENR_UART5EN  HAL_BIT(20)

#define HAL_RCC_CSR_RMVF        HAL_BIT(24)    /* write 1: clear the reset flags */
#define HAL_RCC_CSR_PINRSTF     HAL_BIT(26)
#define HAL_RCC_CSR_PORRSTF     HAL_BIT(27)
#define HAL_RCC_CSR_SFTRSTF     HAL_BIT(28)
#define HAL_RCC_CSR_IWDGRSTF    HAL_BIT(29)

/* ---- Flash interface ---- */
#define HAL_FLASH_ACR           (HAL_FLASH_R_BASE + 0x00UL)
#define HAL_FLASH_KEYR          (HAL_FLASH_R_BASE + 0x04UL)
#define HAL_FLASH_SR            (HAL_FLASH_R_BASE + 0x0CUL)
#define HAL_FLASH_CR            (HAL_FLASH_R_BASE + 0x10UL)
#define HAL_FLASH_AR            (HAL_FLASH_R_BASE + 0x14UL)

#define HAL_FLASH_ACR_LATENCY_MASK (7UL << 0)
#define HAL_FLASH_ACR_LATENCY(n)   ((uint32_t)(n) << 0)   /* wait states: 0 up to 24 MHz, 1 up to 48, 2 above */
#define HAL_FLASH_ACR_PRFTBE    HAL_BIT(4)

#define HAL_FLASH_KEY1          0x45670123UL
#define HAL_FLASH_KEY2          0xCDEF89ABUL

#define HAL_FLASH_SR_BSY        HAL_BIT(0)
#define HAL_FLASH_SR_PGERR      HAL_BIT(2)     /* programming a half-word that was not erased */
#define HAL_FLASH_SR_WRPRTERR   HAL_BIT(4)     /* write-protected page */
#define HAL_FLASH_SR_EOP        HAL_BIT(5)     /* end of operation (write 1 to clear) */

#define HAL_FLASH_CR_PG         HAL_BIT(0)
#define HAL_FLASH_CR_PER        HAL_BIT(1)
#define HAL_FLASH_CR_MER        HAL_BIT(2)
#define HAL_FLASH_CR_STRT       HAL_BIT(6)
#define HAL_FLASH_CR_LOCK       HAL_BIT(7)

/* ---- GPIO (F1 style: 4 configuration bits per pin in CRL/CRH) ---- */
#define HAL_GPIO_CRL(port)      ((port) + 0x00UL)
#define HAL_GPIO_CRH(port)      ((port) + 0x04UL)
#define HAL_GPIO_IDR(port)      ((port) + 0x08UL)
#define HAL_GPIO_ODR(port)      ((port) + 0x0CUL)
#define HAL_GPIO_BSRR(port)     ((port) + 0x10UL)  /* low half sets, high half resets */
#define HAL_GPIO_BRR(port)      ((port) + 0x14UL)

/* ---- AFIO ---- */
#define HAL_AFIO_MAPR           (HAL_AFIO_BASE + 0x04UL)
#define HAL_AFIO_MAPR_USART1_REMAP HAL_BIT(2)      /* USART1 TX/RX on PB6/PB7 */
#define HAL_AFIO_MAPR_SWJ_MASK  (7UL << 24)
#define HAL_AFIO_MAPR_SWJ_NOJTAG (2UL << 24)      /* JTAG off, SWD on: frees PA15, PB3, PB4 */
#define HAL_AFIO_MAPR_SWJ_OFF   (4UL << 24)       /* JTAG and SWD off */

/* ---- USART ---- */
#define HAL_USART_SR(base)      ((base) + 0x00UL)
#define HAL_USART_DR(base)      ((base) + 0x04UL)
#define HAL_USART_BRR(base)     ((base) + 0x08UL)
#define HAL_USART_CR1(base)     ((base) + 0x0CUL)
#define HAL_USART_CR2(base)     ((base) + 0x10UL)
#define HAL_USART_CR3(base)     ((base) + 0x14UL)

#define HAL_USART_SR_PE         HAL_BIT(0)
#define HAL_USART_SR_FE         HAL_BIT(1)
#define HAL_USART_SR_NE         HAL_BIT(2)
#define HAL_USART_SR_ORE        HAL_BIT(3)
#define HAL_USART_SR_RXNE       HAL_BIT(5)
#define HAL_USART_SR_TC         HAL_BIT(6)
#define HAL_USART_SR_TXE        HAL_BIT(7)

#define HAL_USART_CR1_RE        HAL_BIT(2)
#define HAL_USART_CR1_TE        HAL_BIT(3)
#define HAL_USART_CR1_RXNEIE    HAL_BIT(5)
#define HAL_USART_CR1_TCIE      HAL_BIT(6)
#define HAL_USART_CR1_TXEIE     HAL_BIT(7)
#define HAL_USART_CR1_UE        HAL_BIT(13)

/* ---- Independent watchdog (40 kHz LSI, nominal; 30-60 kHz over temperature) ---- */
#define HAL_IWDG_KR             (HAL_IWDG_BASE + 0x00UL)
#define HAL_IWDG_PR             (HAL_IWDG_BASE + 0x04UL)
#define HAL_IWDG_RLR            (HAL_IWDG_BASE + 0x08UL)
#define HAL_IWDG_SR             (HAL_IWDG_BASE + 0x0CUL)
#define HAL_IWDG_KEY_RELOAD     0xAAAAUL
#define HAL_IWDG_KEY_ACCESS     0x5555UL
#define HAL_IWDG_KEY_START      0xCCCCUL
#define HAL_IWDG_SR_PVU         HAL_BIT(0)
#define HAL_IWDG_SR_RVU         HAL_BIT(1)

#endif
