from setuptools import find_packages, setup

package_name = 'skynav_localize'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='skynav developers',
    maintainer_email='skynav@example.org',
    description='Rotation-invariant place recognition on a taught route, with SQLite maps.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': ['localize_node = skynav_localize.node:main'],
        'skynav.nodes': ['localize = skynav_localize.node:LocalizeNode'],
        'skynav.commands': [
            'eval.localization = skynav_localize.cli.eval',
            'map = skynav_localize.cli',
            'map.build = skynav_localize.cli.build',
            'map.info = skynav_localize.cli.info',
        ],
    },
)
