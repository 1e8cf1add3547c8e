from glob import glob

from setuptools import find_packages, setup

package_name = 'activesurv_imaging'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    package_data={package_name: ['py.typed']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
    ],
    install_requires=['setuptools'],
    zip_safe=False,
    maintainer='activesurv developers',
    maintainer_email='dev@activesurv.invalid',
    description=(
        'Imaging module: camera models, simulated cameras, circular-marker detection, '
        'weighted ellipse fit, circle pose, sensor model, imager node.'
    ),
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'activesurv_calibrate = activesurv_imaging.calibrate_cli:main',
            'overhead_locator = activesurv_imaging.overhead_locator_node:main',
            'imager = activesurv_imaging.imager_node:main',
        ],
    },
)
