"""One run's trials (`trials`) and one sitting at the experimenter's desk."""
