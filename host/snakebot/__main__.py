from snakebot.cli import main

main()
