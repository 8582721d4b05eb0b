"""snakesim: an emulated Dynamixel bus of virtual AX-12 servos, and the world they drive."""
